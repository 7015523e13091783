"""The physics node's messages built straight into their slots, for a swarm's many robots.

rclpy's generated ``__init__`` builds every nested default (a TransformStamped makes a Header,
a Time, a Transform, two vectors, imports each class on the way) and then every field goes
through its property setter: about 11 us for a TransformStamped and 36 us for an Odometry,
most of a swarm's per-robot cost. These builders create each object with ``__new__`` and set
its slots to exactly what the constructor and setters leave there (Python floats and
strings, ``array.array('d')`` for sequences, float64 numpy arrays for fixed arrays, a zero
stamp that the runtime replaces), as ``runtime.cdr.decode`` does: the messages compare equal
to, and encode to the same bytes as, those built the usual way (tests/test_physics_batch.py).
"""

from __future__ import annotations

import array

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import (
    Point,
    Pose,
    PoseWithCovariance,
    Quaternion,
    Transform,
    TransformStamped,
    Twist,
    TwistWithCovariance,
    Vector3,
)
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Header

CHECK = Header()._check_fields  # what every constructor sets (ROS_PYTHON_CHECK_FIELDS)


def header(frame_id: str) -> Header:
    """A Header with a zero stamp (the runtime stamps outputs with the tick's time)."""
    t = Time.__new__(Time)
    t._check_fields = CHECK
    t._sec = 0
    t._nanosec = 0
    h = Header.__new__(Header)
    h._check_fields = CHECK
    h._stamp = t
    h._frame_id = frame_id
    return h


def _xyz(cls: type, x: float, y: float, z: float):
    v = cls.__new__(cls)
    v._check_fields = CHECK
    v._x = x
    v._y = y
    v._z = z
    return v


def vector3(x: float, y: float, z: float) -> Vector3:
    """A Vector3 of Python floats."""
    return _xyz(Vector3, x, y, z)


def point(x: float, y: float, z: float) -> Point:
    """A Point of Python floats."""
    return _xyz(Point, x, y, z)


def quaternion(w: float, x: float, y: float, z: float) -> Quaternion:
    """A Quaternion from MuJoCo's order (w, x, y, z)."""
    q = Quaternion.__new__(Quaternion)
    q._check_fields = CHECK
    q._x = x
    q._y = y
    q._z = z
    q._w = w
    return q


def transform_stamped(parent: str, child: str, pos, quat_wxyz) -> TransformStamped:
    """What ``nodes.physics.frames.transform`` builds, from Python floats."""
    tr = Transform.__new__(Transform)
    tr._check_fields = CHECK
    tr._translation = vector3(*pos)
    tr._rotation = quaternion(*quat_wxyz)
    msg = TransformStamped.__new__(TransformStamped)
    msg._check_fields = CHECK
    msg._header = header(parent)
    msg._child_frame_id = child
    msg._transform = tr
    return msg


def odometry(pose7, linear, angular, covariance: np.ndarray, odom_frame: str,
             base_frame: str, twist_covariance: np.ndarray | None = None) -> Odometry:
    """What ``nodes.physics.messages.odometry`` builds: the pose (x, y, z, qw, qx, qy, qz),
    the twist's linear and angular parts (Python floats) and the covariance of both (the
    twist's ``twist_covariance`` where given); each covariance is copied."""
    x, y, z, qw, qx, qy, qz = pose7
    p = Pose.__new__(Pose)
    p._check_fields = CHECK
    p._position = point(x, y, z)
    p._orientation = quaternion(qw, qx, qy, qz)
    pc = PoseWithCovariance.__new__(PoseWithCovariance)
    pc._check_fields = CHECK
    pc._pose = p
    pc._covariance = covariance.copy()
    t = Twist.__new__(Twist)
    t._check_fields = CHECK
    t._linear = vector3(*linear)
    t._angular = vector3(*angular)
    tc = TwistWithCovariance.__new__(TwistWithCovariance)
    tc._check_fields = CHECK
    tc._twist = t
    tc._covariance = (covariance if twist_covariance is None else twist_covariance).copy()
    msg = Odometry.__new__(Odometry)
    msg._check_fields = CHECK
    msg._header = header(odom_frame)
    msg._child_frame_id = base_frame
    msg._pose = pc
    msg._twist = tc
    return msg


def joint_state(names: list[str], pos: array.array, vel: array.array,
                effort: array.array) -> JointState:
    """What ``nodes.physics.messages.joint_state`` builds (the name list is kept, as the
    setter keeps it; the arrays are the message's own)."""
    msg = JointState.__new__(JointState)
    msg._check_fields = CHECK
    msg._header = header("")
    msg._name = names
    msg._position = pos
    msg._velocity = vel
    msg._effort = effort
    return msg


def imu(frame_id: str, quat_wxyz, gyro, accel, covariances) -> Imu:
    """What ``nodes.physics.imu.SimulatedImu.measure`` builds, from Python floats and the
    three covariances (orientation, angular velocity, linear acceleration; copied)."""
    msg = Imu.__new__(Imu)
    msg._check_fields = CHECK
    msg._header = header(frame_id)
    msg._orientation = quaternion(*quat_wxyz)
    msg._angular_velocity = vector3(*gyro)
    msg._linear_acceleration = vector3(*accel)
    o, w, a = covariances
    msg._orientation_covariance = o.copy()
    msg._angular_velocity_covariance = w.copy()
    msg._linear_acceleration_covariance = a.copy()
    return msg
