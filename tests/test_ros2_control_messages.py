"""The controller manager's messages, built slot by slot (nodes.ros2_control.fast_messages),
equal those built the usual way and encode to the same bytes."""

from __future__ import annotations

import pytest
from control_msgs.msg import DynamicJointState, InterfaceValue, JointTrajectoryControllerState
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectoryPoint

from nodes.ros2_control import fast_messages as fast
from runtime.cdr.canonical import canonical_cdr
from runtime.cdr.encode import encode

NAMES = ["shoulder_pan", "shoulder_lift", "elbow"]
POS, VEL, EFF = [0.1, -0.25, 1.5], [0.0, 0.3, -0.7], [2.0, 0.0, -1.25]


def same(fast_msg, usual) -> None:
    assert fast_msg == usual
    assert encode(fast_msg) == encode(usual)
    assert encode(fast_msg) == canonical_cdr(serialize_message(usual), type(usual))


def test_joint_states_and_commands():
    same(fast.joint_state(NAMES, POS, VEL, EFF),
         JointState(name=NAMES, position=POS, velocity=VEL, effort=EFF))
    same(fast.dynamic_joint_state(NAMES, POS, VEL, EFF), DynamicJointState(
        joint_names=NAMES, interface_values=[InterfaceValue(
            interface_names=["position", "velocity", "effort"], values=[p, v, e])
            for p, v, e in zip(POS, VEL, EFF, strict=True)]))
    same(fast.float64_array(POS), Float64MultiArray(data=POS))
    same(fast.float64_array([]), Float64MultiArray())


@pytest.mark.parametrize("moving", [True, False])
def test_the_trajectory_controller_state(moving):
    usual = JointTrajectoryControllerState()
    usual.joint_names = NAMES
    usual.feedback = JointTrajectoryPoint(positions=POS, velocities=VEL)
    if moving:
        usual.reference = JointTrajectoryPoint(positions=EFF, velocities=VEL, accelerations=POS)
        usual.error = JointTrajectoryPoint(positions=[1.0, 2.0, 3.0], velocities=[0.5] * 3)
        usual.output = JointTrajectoryPoint(positions=EFF)
        parts = (fast.point(EFF, VEL, POS), fast.point(POS, VEL),
                 fast.point([1.0, 2.0, 3.0], [0.5] * 3), fast.point(EFF))
    else:
        parts = (fast.point(), fast.point(POS, VEL), fast.point(), fast.point())
    usual.speed_scaling_factor = 1.0
    same(fast.controller_state(NAMES, *parts), usual)


def test_the_diff_drive_odometry():
    import math

    import numpy as np
    from nav_msgs.msg import Odometry

    pose_cov, twist_cov = np.zeros(36), np.zeros(36)
    pose_cov[0], twist_cov[35] = 0.001, 0.03
    usual = Odometry()
    usual.header.frame_id, usual.child_frame_id = "odom", "base_link"
    usual.pose.pose.position.x, usual.pose.pose.position.y = 1.5, -0.25
    usual.pose.pose.orientation.z, usual.pose.pose.orientation.w = math.sin(0.3), math.cos(0.3)
    usual.twist.twist.linear.x, usual.twist.twist.angular.z = 0.4, -0.2
    usual.pose.covariance[0], usual.twist.covariance[35] = 0.001, 0.03
    same(fast.odometry(1.5, -0.25, math.sin(0.3), math.cos(0.3), 0.4, -0.2, pose_cov,
                       twist_cov, "odom", "base_link"), usual)


def test_an_inactive_trajectory_controllers_state_is_the_empty_message():
    from nodes.ros2_control.controllers.joint_trajectory_controller import STATE
    from nodes.ros2_control.registry import controller_class

    cls = controller_class("joint_trajectory_controller/JointTrajectoryController")
    ctrl = cls("jtc", cls.Params(joints=NAMES, command_interfaces=["position"]))
    same(ctrl.empty_message(STATE), JointTrajectoryControllerState())


@pytest.mark.parametrize("joints", [1, 2, 3, 6, 7])
def test_the_broadcasters_packed_bytes_are_the_encoders(joints):
    import random

    rng = random.Random(joints)
    names = [f"joint_{i}" + "x" * (i % 4) for i in range(joints)]  # every alignment
    packer = fast.BroadcasterPacker(names)
    for _ in range(3):  # the same layout packed again with other values
        p, v, e = ([rng.uniform(-1e3, 1e3) for _ in names] for _ in range(3))
        js = fast.joint_state(names, p, v, e)
        djs = fast.dynamic_joint_state(names, p, v, e)
        assert packer.pack_joint_state(p, v, e) == encode(js)[12:]  # past header + stamp
        assert packer.pack_dynamic(p, v, e) == encode(djs)[12:]
        assert encode(djs) == canonical_cdr(serialize_message(djs), DynamicJointState)


def test_a_message_handed_with_its_bytes_gets_the_ticks_stamp_in_front():
    from nodes.contract import Tick, encoded_message, take_output_marks
    from runtime.exchange import prepare_outputs

    take_output_marks()
    packer = fast.BroadcasterPacker(NAMES)
    msg = fast.joint_state(NAMES, POS, VEL, EFF)
    encoded_message(msg, packer.pack_joint_state(POS, VEL, EFF))
    items = prepare_outputs("physics", {"/joint_states": JointState},
                            {"/joint_states": "/r/joint_states"}, Tick(7, 1_250_000_000),
                            {"/joint_states": msg})
    assert msg.header.stamp.sec == 1 and msg.header.stamp.nanosec == 250_000_000
    assert items == [("/r/joint_states", encode(msg))]
    assert take_output_marks() is None
    bad = JointState(name=["other"])  # a mark is the step's own: not for another message
    encoded_message(msg, b"stale")
    items = prepare_outputs("physics", {"/joint_states": JointState},
                            {"/joint_states": "/joint_states"}, Tick(8, 0), {"/joint_states": bad})
    assert items == [("/joint_states", encode(bad))]


def test_joint_states_read_as_a_mapping_and_as_lists():
    from nodes.ros2_control.interface import JointReading, JointStates

    state = JointStates(NAMES)
    assert list(state) == NAMES and len(state) == 3 and state["elbow"] == JointReading(0.0)
    state.refresh(list(POS), list(VEL), list(EFF))
    kept = state["shoulder_lift"]
    assert kept == JointReading(-0.25, 0.3, 0.0) and "elbow" in state and "x" not in state
    assert dict(state) == {n: JointReading(p, v, e) for n, p, v, e in
                           zip(NAMES, POS, VEL, EFF, strict=True)}
    state.refresh([9.0] * 3, [0.0] * 3, [0.0] * 3)
    assert state["shoulder_lift"].position == 9.0 and kept.position == -0.25  # kept: unchanged
    assert state.positions == [9.0] * 3
    with pytest.raises(KeyError):
        state["x"]
