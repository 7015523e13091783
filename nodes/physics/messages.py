"""Building the physics node's ROS messages from MuJoCo state (numpy in, messages out)."""

from __future__ import annotations

import array

import numpy as np
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from plan.poses import yaw
from plan.rot3 import mat_t_vec

# Ground truth: tiny but non-zero variances, so consumers that invert them do not blow up.
TRUTH_COVARIANCE = array.array("d", np.diag(np.full(6, 1e-9)).ravel().tobytes())


def f64(values: np.ndarray) -> array.array:
    """A float64 array.array (what rclpy stores for float64[] fields, without a copy loop)."""
    out = array.array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


def odometry(qpos: np.ndarray, qvel: np.ndarray, odom_frame: str, base_frame: str) -> Odometry:
    """Odometry of a free-joint base: pose in ``odom_frame``, twist in ``base_frame``.

    MuJoCo's free joint: qpos = (x, y, z, qw, qx, qy, qz); qvel[:3] is the linear velocity
    in the world frame and qvel[3:6] the angular velocity in the body frame.
    """
    msg = Odometry()
    msg.header.frame_id = odom_frame
    msg.child_frame_id = base_frame
    p = msg.pose.pose
    p.position.x, p.position.y, p.position.z = (float(v) for v in qpos[:3])
    w, x, y, z = (float(v) for v in qpos[3:7])
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = x, y, z, w
    t = msg.twist.twist
    t.linear.x, t.linear.y, t.linear.z = mat_t_vec(quat_to_mat(qpos[3:7]), qvel[:3])
    t.angular.x, t.angular.y, t.angular.z = (float(v) for v in qvel[3:6])
    msg.pose.covariance = TRUTH_COVARIANCE
    msg.twist.covariance = TRUTH_COVARIANCE
    return msg


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def yaw_of(q: np.ndarray) -> float:
    """Heading (rotation about z) of a quaternion array (w, x, y, z): ``plan.poses.yaw``."""
    w, x, y, z = (float(v) for v in q)
    return yaw(w, x, y, z)


def joint_state(names: list[str], pos: np.ndarray, vel: np.ndarray,
                effort: np.ndarray) -> JointState:
    """A JointState with the given joints (frame id empty, as usual for joint states)."""
    msg = JointState()
    msg.name = names
    msg.position = f64(pos)
    msg.velocity = f64(vel)
    msg.effort = f64(effort)
    return msg


WORLD_VERSION = "world_version"  # the layout dimension that carries it (no data of its own)
WORLD_EDITS = "world_edits:"  # the one that says what is in the world, when not the plan's


def world_state(qpos: np.ndarray, qvel: np.ndarray, version: int = 0, label: str = ""
                ) -> Float64MultiArray:
    """The mirror of the world for sensors: data = qpos then qvel, labelled in the layout;
    once an event or a client's edit changed the world, a third dimension says how many
    are in it (its ``size``; the qpos layout is that world's) and, where they are not the
    scenario's first events, a fourth one which (its label after ``world_edits:``,
    ``nodes.physics.world_events.LiveWorld.label``)."""
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label="qpos", size=len(qpos), stride=len(qpos)),
                      MultiArrayDimension(label="qvel", size=len(qvel), stride=len(qvel))]
    if version:
        msg.layout.dim.append(MultiArrayDimension(label=WORLD_VERSION, size=version, stride=0))
    if label:
        msg.layout.dim.append(MultiArrayDimension(label=WORLD_EDITS + label, size=0, stride=0))
    msg.data = f64(np.concatenate([qpos, qvel]))
    return msg


def world_version(msg: Float64MultiArray) -> tuple[int, str]:
    """(how many events and edits are in the world a world state shows, which: '' for the
    scenario's first ones); (0, '') for the world as loaded."""
    version, label = 0, ""
    for dim in msg.layout.dim[2:]:
        if dim.label == WORLD_VERSION:
            version = int(dim.size)
        elif dim.label.startswith(WORLD_EDITS):
            label = dim.label[len(WORLD_EDITS):]
    return version, label


def twist_of(msg: Twist | TwistStamped | None) -> tuple[float, float]:
    """(linear.x, angular.z) of a Twist or TwistStamped; a missing command is a stop."""
    if msg is None:
        return 0.0, 0.0
    twist = msg.twist if isinstance(msg, TwistStamped) else msg
    return float(twist.linear.x), float(twist.angular.z)
