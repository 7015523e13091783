"""The physics node's TF tree and IMU against MuJoCo's own poses and sensors, the latched
output contract, and the load-time checks of /cmd_vel's type and of latched topics."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import yaml
from geometry_msgs.msg import Twist, TwistStamped
from std_msgs.msg import Float64MultiArray

from descriptions.load import load_scenario
from nodes.contract import NodeConfig, Tick
from nodes.physics.node import PhysicsNode
from plan.errors import ScenarioError
from runtime.exchange import StepContractError, prepare_outputs
from tests.helpers import ROOT
from tests.worlds import write_world

TICK = 20_000_000
NAV = ROOT / "scenarios" / "nav.yaml"


def make(world, seed: int = 0, **params) -> PhysicsNode:
    """A reset physics node on ``world``."""
    node = PhysicsNode()
    node.reset(seed, NodeConfig("physics", PhysicsNode.Params(**params), TICK, TICK, world))
    return node


def pose_of(t) -> tuple[np.ndarray, np.ndarray]:
    """(rotation matrix, translation) of a geometry_msgs/Transform."""
    r, p = t.rotation, t.translation
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, np.array([r.w, r.x, r.y, r.z]))
    return mat.reshape(3, 3), np.array([p.x, p.y, p.z])


def in_root(transforms: list, frame: str) -> tuple[str, np.ndarray, np.ndarray]:
    """(root frame, rotation, translation) of ``frame`` composed along the tree's parents."""
    parent = {t.child_frame_id: t for t in transforms}
    assert len(parent) == len(transforms), "a frame has two parents"
    rot, pos = np.eye(3), np.zeros(3)
    while frame in parent:
        t = parent[frame]
        r, p = pose_of(t.transform)
        rot, pos = r @ rot, r @ pos + p
        frame = t.header.frame_id
    return frame, rot, pos


def test_every_sensor_frame_composes_to_mujocos_pose_of_it(tmp_path):
    node = make(write_world(tmp_path), start={"x": 1.0, "y": -0.5, "yaw": 0.7})
    static = node.step(Tick(0, 0), {})["/tf_static"].transforms
    head = Float64MultiArray(data=[0.8, -0.4])  # a moving head: pan_link, tilt_link on /tf
    for k in range(1, 40):
        out = node.step(Tick(k, k * TICK), {"/cmd_vel": Twist(), "/joint_commands": head})
    assert "/tf_static" not in out
    tree = [*static, *out["/tf"].transforms]
    d, m = node.data, node.model
    cam = m.camera("rgbd").id
    expected = {
        "laser": (d.site_xmat[m.site("laser").id], d.site_xpos[m.site("laser").id]),
        "imu_link": (d.site_xmat[m.site("imu").id], d.site_xpos[m.site("imu").id]),
        # REP-103 optical axes: x right, y down, z forward; MuJoCo's camera looks along -z
        "camera_color_optical_frame": (d.cam_xmat[cam].reshape(3, 3) @ np.diag([1, -1, -1]),
                                       d.cam_xpos[cam]),
        "camera_depth_optical_frame": (d.cam_xmat[cam].reshape(3, 3) @ np.diag([1, -1, -1]),
                                       d.cam_xpos[cam]),
    }
    for frame, (rot, pos) in expected.items():
        root, got_rot, got_pos = in_root(tree, frame)
        assert root == "map", frame
        np.testing.assert_allclose(got_rot, np.reshape(rot, (3, 3)), atol=1e-9, err_msg=frame)
        np.testing.assert_allclose(got_pos, pos, atol=1e-9, err_msg=frame)
    _, link_rot, _ = in_root(tree, "camera_link")  # REP-103 body axes: x along the view
    np.testing.assert_allclose(link_rot[:, 0], -d.cam_xmat[cam].reshape(3, 3)[:, 2], atol=1e-9)
    assert math.isclose(list(out["/joint_states"].position)[2], 0.8, abs_tol=0.1)


def test_odom_to_base_link_is_the_odometry_and_map_to_odom_the_configured_offset(tmp_path):
    node = make(write_world(tmp_path), tf={"map_to_odom": {"x": 1.0, "y": 2.0, "yaw": 0.5}})
    node.step(Tick(0, 0), {})
    forward = Twist()
    forward.linear.x = 0.4
    for k in range(1, 30):
        out = node.step(Tick(k, k * TICK), {"/cmd_vel": forward})
        by_child = {t.child_frame_id: t for t in out["/tf"].transforms}
        odom = out["/odom"].pose.pose
        tf = by_child["base_link"]
        assert tf.header.frame_id == "odom"
        assert (tf.transform.translation.x, tf.transform.translation.y,
                tf.transform.translation.z) == (odom.position.x, odom.position.y,
                                                 odom.position.z)
        assert tf.transform.rotation == odom.orientation
    offset = by_child["odom"]
    assert offset.header.frame_id == "map" and offset.transform.translation.x == 1.0
    assert math.isclose(2 * math.atan2(offset.transform.rotation.z,
                                       offset.transform.rotation.w), 0.5)
    quiet = make(write_world(tmp_path), tf={"map_frame": None})
    assert [t.child_frame_id for t in quiet.step(Tick(0, 0), {})["/tf"].transforms][0] \
        == "base_link"


def test_latched_outputs_come_with_the_first_activation_after_each_reset_only(tmp_path):
    world = write_world(tmp_path)
    node = make(world)
    plan = load_scenario(NAV).nodes["physics"]
    first = node.step(Tick(0, 0), {})
    later = node.step(Tick(1, TICK), {})
    assert "/tf_static" in first and "/tf_static" not in later
    args = ("physics", plan.declared_outputs, plan.output_names)
    items = prepare_outputs(*args, Tick(0, 0), first, plan.latched, first=True)
    assert "/tf_static" in dict(items)
    with pytest.raises(StepContractError, match="latched: due at the first activation only"):
        prepare_outputs(*args, Tick(1, TICK), first, plan.latched, first=False)
    with pytest.raises(StepContractError, match=r"missing \['/tf_static'\]"):
        prepare_outputs(*args, Tick(0, 0), later, plan.latched, first=True)
    node.reset(0, node.config)
    assert "/tf_static" in node.step(Tick(0, 0), {})


def settle(node: PhysicsNode, ticks: int) -> list:
    """Step a robot that is told nothing (it stands still) and return its /imu messages."""
    node.step(Tick(0, 0), {})
    return [node.step(Tick(k, k * TICK), {})["/imu"] for k in range(1, ticks)]


def vector(v) -> np.ndarray:
    """A geometry_msgs/Vector3 as an array."""
    return np.array([v.x, v.y, v.z])


def test_imu_at_rest_reads_gravity_up_and_the_start_heading_with_rep145_covariances(tmp_path):
    node = make(write_world(tmp_path), start={"x": 0.0, "y": 0.0, "yaw": 1.2})
    imu = settle(node, 60)[-20:]  # settled on its wheels
    accel = np.mean([vector(m.linear_acceleration) for m in imu], axis=0)
    assert abs(accel[2] - 9.81) < 0.1 and np.hypot(accel[0], accel[1]) < 0.1
    assert max(abs(vector(m.angular_velocity)).max() for m in imu) < 0.02
    for m in imu:
        o = m.orientation
        assert abs(math.atan2(2 * (o.w * o.z + o.x * o.y), 1 - 2 * (o.y ** 2 + o.z ** 2))
                   - 1.2) < 0.02
        assert m.header.frame_id == "imu_link"
    p = node.params.imu
    for field, stddev in (("orientation", p.orientation_stddev),
                          ("angular_velocity", p.angular_velocity_stddev),
                          ("linear_acceleration", p.linear_acceleration_stddev)):
        cov = np.reshape(getattr(imu[0], f"{field}_covariance"), (3, 3))
        np.testing.assert_array_equal(cov, np.diag([stddev ** 2] * 3), err_msg=field)


def test_imu_bias_is_constant_and_noise_white_around_the_noiseless_sensor(tmp_path):
    world = write_world(tmp_path)
    zero = {"angular_velocity_stddev": 0, "angular_velocity_bias_stddev": 0,
            "linear_acceleration_stddev": 0, "linear_acceleration_bias_stddev": 0,
            "orientation_stddev": 0}
    truth = settle(make(world, imu=zero), 200)
    biased = settle(make(world, imu={**zero, "linear_acceleration_bias_stddev": 0.5}), 200)
    noisy = settle(make(world, imu={**zero, "linear_acceleration_stddev": 0.3}), 200)
    offset = np.array([vector(b.linear_acceleration) - vector(t.linear_acceleration)
                       for b, t in zip(biased, truth, strict=True)])
    assert np.ptp(offset, axis=0).max() < 1e-12 and 0 < np.abs(offset[0]).max() < 2.5
    error = np.array([vector(n.linear_acceleration) - vector(t.linear_acceleration)
                      for n, t in zip(noisy, truth, strict=True)])
    assert np.all(np.abs(error.mean(axis=0)) < 0.08)
    assert np.all(np.abs(error.std(axis=0) - 0.3) < 0.06)
    assert [vector(n.angular_velocity).tolist() for n in noisy] \
        == [vector(t.angular_velocity).tolist() for t in truth]


def test_imu_noise_depends_on_the_seed_only(tmp_path):
    world = write_world(tmp_path)

    def accel(seed):
        return [vector(m.linear_acceleration).tolist() for m in settle(make(world, seed), 10)]

    assert accel(1) == accel(1) != accel(2)


def test_the_world_must_have_the_imus_sensors_and_the_frames_sites(tmp_path):
    world = write_world(tmp_path)
    model = mujoco.MjModel.from_xml_path(str(world))
    problems = PhysicsNode.world_problems(PhysicsNode.Params(imu={"gyro": "nope"}), model, None)
    assert problems[0][0] == "params.imu.gyro" and "'nope'" in problems[0][1]
    problems = PhysicsNode.world_problems(
        PhysicsNode.Params(imu={"gyro": "imu_accel"}), model, None)
    assert "is not a gyro sensor" in problems[0][1]
    problems = PhysicsNode.world_problems(
        PhysicsNode.Params(tf={"sites": {"lidar": "laser"}}), model, None)
    assert problems[0][0] == "params.tf.sites" and "no site 'lidar'" in problems[0][1]
    problems = PhysicsNode.world_problems(
        PhysicsNode.Params(tf={"cameras": [{"camera": "front"}]}), model, None)
    assert problems[0][0] == "params.tf.cameras[0].camera"
    assert PhysicsNode.world_problems(PhysicsNode.Params(), model, None) == []


def test_physics_drives_with_a_twist_stamped_command(tmp_path):
    node = make(write_world(tmp_path), enable_stamped_cmd_vel=True)
    cmd = TwistStamped()
    cmd.twist.linear.x = 0.5
    node.step(Tick(0, 0), {})
    for k in range(1, 51):
        node.step(Tick(k, k * TICK), {"/cmd_vel": cmd})
    assert node.metrics()["x"] > 0.35


@pytest.mark.parametrize("stamped", ["physics", "control"])
def test_a_cmd_vel_type_mismatch_is_refused_naming_the_physics_parameter(stamped):
    with pytest.raises(ScenarioError) as error:
        load_scenario(NAV, {f"nodes.{stamped}.params.enable_stamped_cmd_vel": True})
    text = str(error.value)
    assert error.value.key == "nodes[0] (physics).params.enable_stamped_cmd_vel"
    assert "or nodes[3] (control).params.enable_stamped_cmd_vel." in text
    wanted, sent = (("TwistStamped", "Twist") if stamped == "physics"
                    else ("Twist", "TwistStamped"))
    assert f"takes /cmd_vel as geometry_msgs/msg/{wanted}, but" in text
    assert f"publishes /cmd_vel as geometry_msgs/msg/{sent}." in text


def test_twist_stamped_on_both_ends_loads():
    scenario = load_scenario(NAV, {"nodes.physics.params.enable_stamped_cmd_vel": True,
                                   "nodes.control.params.enable_stamped_cmd_vel": True})
    assert scenario.topics["/cmd_vel"] is TwistStamped
    assert scenario.nodes["physics"].inputs[0].msg_type is TwistStamped


def test_a_latched_topic_cannot_be_a_scheduled_input(tmp_path):
    doc = yaml.safe_load(NAV.read_text())
    doc["world"] = str(ROOT / "scenarios" / "worlds" / "nav.xml")
    doc["nodes"].append({"name": "watcher", "kind": "counter", "rate": 50,
                         "params": {"output": "/watched"},
                         "inputs": [{"topic": "/tf_static", "mode": "same_tick"}]})
    path = tmp_path / "latched_input.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ScenarioError) as error:
        load_scenario(path)
    assert error.value.key == "nodes[4] (watcher).inputs[0].topic"
    assert "/tf_static is published once, latched, by node 'physics'" in str(error.value)
    scenario = load_scenario(NAV)
    assert scenario.latched_topics == {"/tf_static"}
    assert scenario.nodes["physics"].latched_topics == {"/tf_static"}
