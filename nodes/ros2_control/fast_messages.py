"""The controller manager's messages built straight into their slots, at every update.

A default JointTrajectoryControllerState builds four JointTrajectoryPoints and four
MultiDOFJointTrajectoryPoints, each with its Duration, and every field then goes through its
property setter: a third of the manager's step (bench/README). As ``nodes.physics.
fast_messages`` does for physics, these builders create each object with ``__new__`` and set
its slots to exactly what the constructor and setters leave there (lists of str, ``array('d')``
for float64 sequences): the messages compare equal to, and encode to the same bytes as, those
built the usual way (tests/test_ros2_control_messages.py).
"""

from __future__ import annotations

from array import array

import numpy as np
from builtin_interfaces.msg import Duration
from control_msgs.msg import DynamicJointState, InterfaceValue, JointTrajectoryControllerState
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64MultiArray, MultiArrayLayout
from trajectory_msgs.msg import JointTrajectoryPoint, MultiDOFJointTrajectoryPoint

from nodes.cdr_layout import FixedLayout
from nodes.physics.fast_messages import CHECK, header
from nodes.physics.fast_messages import joint_state as _joint_state
from nodes.physics.fast_messages import odometry as _odometry

INTERFACES = ("position", "velocity", "effort")


def _duration() -> Duration:
    d = Duration.__new__(Duration)
    d._check_fields = CHECK
    d._sec = 0
    d._nanosec = 0
    return d


def point(positions=(), velocities=(), accelerations=()) -> JointTrajectoryPoint:
    """A JointTrajectoryPoint of these float sequences, no effort, time_from_start 0."""
    p = JointTrajectoryPoint.__new__(JointTrajectoryPoint)
    p._check_fields = CHECK
    p._positions = array("d", positions)
    p._velocities = array("d", velocities)
    p._accelerations = array("d", accelerations)
    p._effort = array("d")
    p._time_from_start = _duration()
    return p


def _multi_dof_point() -> MultiDOFJointTrajectoryPoint:
    p = MultiDOFJointTrajectoryPoint.__new__(MultiDOFJointTrajectoryPoint)
    p._check_fields = CHECK
    p._transforms = []
    p._velocities = []
    p._accelerations = []
    p._time_from_start = _duration()
    return p


def controller_state(joints: list[str], reference: JointTrajectoryPoint,
                     feedback: JointTrajectoryPoint, error: JointTrajectoryPoint,
                     output: JointTrajectoryPoint, speed_scaling_factor: float = 1.0
                     ) -> JointTrajectoryControllerState:
    """~/controller_state of a trajectory controller (no multi-DOF joints; speed scaling 1,
    0 in the empty message an inactive controller's topic carries)."""
    msg = JointTrajectoryControllerState.__new__(JointTrajectoryControllerState)
    msg._check_fields = CHECK
    msg._header = header("")
    msg._joint_names = list(joints)
    msg._reference = reference
    msg._feedback = feedback
    msg._error = error
    msg._output = output
    msg._multi_dof_joint_names = []
    msg._multi_dof_reference = _multi_dof_point()
    msg._multi_dof_feedback = _multi_dof_point()
    msg._multi_dof_error = _multi_dof_point()
    msg._multi_dof_output = _multi_dof_point()
    msg._speed_scaling_factor = speed_scaling_factor
    return msg


def joint_state(names: list[str], positions, velocities, efforts):
    """The joint state broadcaster's sensor_msgs/JointState."""
    return _joint_state(list(names), array("d", positions), array("d", velocities),
                        array("d", efforts))


def dynamic_joint_state(names: list[str], positions, velocities, efforts
                        ) -> DynamicJointState:
    """The broadcaster's control_msgs/DynamicJointState: position, velocity and effort of
    every joint (its values' interface names one list, which no one changes)."""
    values = []
    append, new, interfaces = values.append, InterfaceValue.__new__, list(INTERFACES)
    for p, v, e in zip(positions, velocities, efforts, strict=True):
        iv = new(InterfaceValue)
        iv._check_fields = CHECK
        iv._interface_names = interfaces
        iv._values = array("d", (p, v, e))
        append(iv)
    msg = DynamicJointState.__new__(DynamicJointState)
    msg._check_fields = CHECK
    msg._header = header("")
    msg._joint_names = list(names)
    msg._interface_values = values
    return msg


class BroadcasterPacker:
    """The CDR bytes past the header's stamp of a joint state broadcaster's JointState and
    DynamicJointState over fixed joints (at least one), each in one ``struct`` call
    (``nodes.cdr_layout``): the names, counts and alignments are the same at every update,
    only the values change."""

    def __init__(self, names: list[str]):
        n = len(names)
        self.pack_joint_state = (FixedLayout().strings(names).count(n).doubles(n).count(n)
                                 .doubles(n).count(n).doubles(n).packer_of_runs())
        """``pack_joint_state(positions, velocities, efforts)``: the JointState's bytes past
        the stamp (a float each per joint, in order)."""
        dynamic = FixedLayout().strings(names).count(n)
        for _ in names:
            dynamic.strings(INTERFACES).count(len(INTERFACES)).doubles(len(INTERFACES))
        self.pack_dynamic = dynamic.packer_of_columns(len(INTERFACES))
        """``pack_dynamic(positions, velocities, efforts)``: the DynamicJointState's."""


def float64_array(data) -> Float64MultiArray:
    """A Float64MultiArray with an empty layout."""
    layout = MultiArrayLayout.__new__(MultiArrayLayout)
    layout._check_fields = CHECK
    layout._dim = []
    layout._data_offset = 0
    msg = Float64MultiArray.__new__(Float64MultiArray)
    msg._check_fields = CHECK
    msg._layout = layout
    msg._data = array("d", data)
    return msg


def odometry(x: float, y: float, qz: float, qw: float, linear: float, angular: float,
             pose_covariance: np.ndarray, twist_covariance: np.ndarray, frame_id: str,
             child_frame_id: str) -> Odometry:
    """A diff drive's ~/odom: a planar pose (x, y, the heading as qz, qw) and twist (linear
    x, angular z), each covariance a float64 array of 36 (copied)."""
    return _odometry((x, y, 0.0, qw, 0.0, 0.0, qz), (linear, 0.0, 0.0), (0.0, 0.0, angular),
                     pose_covariance, frame_id, child_frame_id, twist_covariance)
