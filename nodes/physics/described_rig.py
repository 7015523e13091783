"""The physics node's side of a described robot (one a reader of descriptions.readers made,
whatever its format: URDF, xacro, USD): its names taken from its robot model instead of the
physics parameters' conventions, and what robot_state_publisher and joint_state_broadcaster
would publish for it: TF for every link under the description's own names (fixed joints on
/tf_static, moving ones and ``odom -> root`` on /tf), joint states of every movable joint
under its joint names, and its URDF on /robot_description."""

from __future__ import annotations

import mujoco
import numpy as np
from geometry_msgs.msg import TransformStamped
from std_msgs.msg import String

from descriptions.robot_model import RobotModel
from descriptions.robot_state import RobotStateFrames
from nodes.physics import messages as m
from nodes.physics.frames import TfParams, transform

ROBOT_DESCRIPTION = "/robot_description"


def described_params(params, robot: RobotModel):
    """The physics parameters with the robot model's names (already scoped to the robot):
    its root link as base body and frame, its drive, its commanded joints and its IMU."""
    imu = params.imu
    sensor = robot.sensor("imu")
    if imu is not None:
        imu = None if sensor is None else imu.model_copy(update={
            "site": sensor.mujoco_name, "frame_id": sensor.link,
            "gyro": f"{sensor.mujoco_name}_gyro", "accelerometer": f"{sensor.mujoco_name}_accel",
            "orientation": f"{sensor.mujoco_name}_quat"})
    drive = robot.drive
    return params.model_copy(update={
        "base_body": robot.base, "base_frame": robot.base_link,
        "odom_frame": robot.frame_prefix + params.odom_frame,
        "wheel_joints": None if drive is None else (drive.left_joint, drive.right_joint),
        "wheel_actuators": ("", "") if drive is None else (drive.left_actuator,
                                                           drive.right_actuator),
        "position_joints": [a.joint for a in robot.actuated],
        "position_actuators": [a.actuator for a in robot.actuated],
        "imu": imu, "start": None})


def _msg(t) -> TransformStamped:
    return transform(t.parent, t.child, t.pos, t.quat)


class DescribedRobotFrames:
    """``nodes.physics.frames.RobotFrames``' interface ``static`` (every
    fixed joint, once), ``dynamic`` (map -> odom, odom -> root link, every moving joint), for
    a described robot."""

    def __init__(self, model: mujoco.MjModel, params: TfParams, robot: RobotModel,
                 odom_frame: str):
        self.frames = RobotStateFrames(model, robot, odom_frame)
        self.odom_frame, self.base_frame = robot.frame_prefix + odom_frame, robot.base_link
        self.mobile = self.publishes_base = robot.mobile  # odom -> base: a mobile robot's
        self.moving: list = []  # no body pairs: its moving links are ``links``
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)  # fixed joints: the same in every state
        self.static = [_msg(t) for t in self.frames.static(data)]
        mo = params.map_to_odom
        self.map_to_odom = (None if params.map_frame is None else
                            (params.map_frame, (mo.x, mo.y, 0.0),
                             (np.cos(mo.yaw / 2), 0.0, 0.0, np.sin(mo.yaw / 2))))

    @property
    def needs_kinematics(self) -> bool:
        """Whether any transform depends on body positions (a moving joint)."""
        return self.frames.has_moving

    def dynamic(self, data: mujoco.MjData, base_qpos: np.ndarray) -> list[TransformStamped]:
        """map -> odom, odom -> the root link (a mobile robot's free joint) and the moving
        joints (from ``data``'s current kinematics)."""
        out = []
        if self.map_to_odom is not None:
            frame, pos, quat = self.map_to_odom
            out.append(transform(frame, self.odom_frame, pos, quat))
        if self.mobile:
            out.append(transform(self.odom_frame, self.base_frame, base_qpos[:3],
                                 base_qpos[3:7]))
        return out + self.links(data)

    def links(self, data: mujoco.MjData) -> list[TransformStamped]:
        """The moving joints' transforms, parent link -> child link."""
        return [_msg(t) for t in self.frames.moving(data)]

    @property
    def state_joints(self) -> tuple[list[str], list[int], list[int]]:
        """The joints /joint_states carries: names (the description's), qpos and dof
        addresses."""
        joints = self.frames.joints
        return [n for n, _, _ in joints], [q for _, q, _ in joints], [d for _, _, d in joints]

    def joint_state(self, data: mujoco.MjData):
        """sensor_msgs/JointState of every movable joint, under the description's names."""
        s = self.frames.joint_states(data)
        return m.joint_state(list(s.names), np.array(s.position), np.array(s.velocity),
                             np.array(s.effort))


def robot_description(urdf_text: str) -> String:
    """The /robot_description message: the robot's URDF (expanded, or written from its USD),
    as robot_state_publisher serves it."""
    return String(data=urdf_text)
