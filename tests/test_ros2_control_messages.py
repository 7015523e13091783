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
