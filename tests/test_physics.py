"""Physics node: timestep checks, driving, pan-tilt commands, odometry and collisions."""

from __future__ import annotations

import math

import pytest
from geometry_msgs.msg import Twist
from std_msgs.msg import Float64MultiArray

from nodes.contract import NodeConfig, Tick
from nodes.physics.node import PhysicsNode
from tests.worlds import write_world

TICK = 20_000_000


def make(world, period=TICK, **params) -> PhysicsNode:
    """A reset physics node on ``world``."""
    node = PhysicsNode()
    node.reset(0, NodeConfig("physics", PhysicsNode.Params(**params), TICK, period, world))
    return node


def twist(v: float, w: float = 0.0) -> Twist:
    """A planar velocity command."""
    msg = Twist()
    msg.linear.x, msg.angular.z = v, w
    return msg


def run(node: PhysicsNode, ticks: range, inputs: dict) -> dict:
    """Step ``node`` over ``ticks`` with the same inputs; return the last outputs."""
    out = {}
    for k in ticks:
        out = node.step(Tick(k, k * TICK), inputs if k else {})
    return out


def test_tick_zero_publishes_the_initial_state_without_integrating(tmp_path):
    node = make(write_world(tmp_path), start={"x": 1.0, "y": 2.0, "yaw": 0.5})
    out = node.step(Tick(0, 0), {})
    odom = out["/odom"]
    assert (odom.pose.pose.position.x, odom.pose.pose.position.y) == (1.0, 2.0)
    assert odom.header.frame_id == "odom" and odom.child_frame_id == "base_link"
    assert math.isclose(node.metrics()["yaw"], 0.5, abs_tol=1e-9)
    assert len(out["/cosim/world_state"].data) == node.model.nq + node.model.nv
    assert list(out["/joint_states"].name) == ["left_wheel_joint", "right_wheel_joint",
                                               "pan_joint", "tilt_joint"]


def test_half_a_metre_per_second_for_two_seconds_moves_about_a_metre(tmp_path):
    node = make(write_world(tmp_path), start={"x": 0.0, "y": 0.0, "yaw": 0.0})
    out = run(node, range(101), {"/cmd_vel": twist(0.5)})  # 100 periods of 20 ms
    m = node.metrics()
    assert 0.85 < m["x"] < 1.02  # acceleration ramp and a little wheel slip
    assert abs(m["y"]) < 0.02 and abs(m["yaw"]) < 0.02
    assert math.isclose(out["/odom"].twist.twist.linear.x, 0.5, abs_tol=0.03)
    assert m["collisions"] == 0


def test_turning_in_place(tmp_path):
    node = make(write_world(tmp_path))
    run(node, range(51), {"/cmd_vel": twist(0.0, 1.0)})
    m = node.metrics()
    assert 0.8 < m["yaw"] < 1.05 and math.hypot(m["x"], m["y"]) < 0.05


def test_absent_command_means_standing_still(tmp_path):
    node = make(write_world(tmp_path))
    run(node, range(50), {})
    assert math.hypot(node.metrics()["x"], node.metrics()["y"]) < 1e-3


def test_pan_tilt_follows_joint_commands(tmp_path):
    node = make(write_world(tmp_path))
    cmd = Float64MultiArray(data=[0.6, -0.3])
    out = run(node, range(101), {"/joint_commands": cmd})
    pos = list(out["/joint_states"].position)
    assert math.isclose(pos[2], 0.6, abs_tol=0.05) and math.isclose(pos[3], -0.3, abs_tol=0.05)


def test_wrong_joint_command_length_is_noted_once_and_ignored(tmp_path):
    node = make(write_world(tmp_path))
    good = Float64MultiArray(data=[0.6, -0.3])
    bad = Float64MultiArray(data=[0.1, 0.2, 0.3])
    run(node, range(50), {"/joint_commands": good})
    run(node, range(50, 101), {"/joint_commands": bad})
    notes = node.take_notes()
    assert len(notes) == 1 and "carries 3 positions, this robot takes 2" in notes[0]
    out = run(node, range(101, 102), {"/joint_commands": bad})
    pos = list(out["/joint_states"].position)  # still at the last good command
    assert math.isclose(pos[2], 0.6, abs_tol=0.05) and math.isclose(pos[3], -0.3, abs_tol=0.05)


def test_period_not_a_multiple_of_the_timestep_is_refused(tmp_path):
    world = write_world(tmp_path, timestep="0.003")
    with pytest.raises(ValueError, match=r"timestep 3000000 ns does not divide .* period 20ms"):
        make(world)


def test_timestep_not_a_whole_number_of_ns_is_refused(tmp_path):
    with pytest.raises(ValueError, match="not a whole number of nanoseconds"):
        make(write_world(tmp_path, timestep="0.0000000015"))


def test_driving_into_a_wall_counts_one_collision_event(tmp_path):
    wall = '<geom name="wall" type="box" pos="1.0 0 0.5" size="0.05 2 0.5"/>'
    node = make(write_world(tmp_path, wall))
    run(node, range(151), {"/cmd_vel": twist(0.4)})
    m = node.metrics()
    assert m["collisions"] >= 1
    assert m["collisions"] <= 3  # events, not per-substep contact counts (that would be 100s)
    assert m["x"] < 1.0 - 0.05 - 0.17


def test_same_inputs_same_outputs(tmp_path):
    world = write_world(tmp_path)
    a, b = make(world), make(world)
    for k in range(30):
        inputs = {"/cmd_vel": twist(0.3, 0.5)} if k else {}
        assert (list(a.step(Tick(k, k * TICK), inputs)["/cosim/world_state"].data)
                == list(b.step(Tick(k, k * TICK), inputs)["/cosim/world_state"].data))
