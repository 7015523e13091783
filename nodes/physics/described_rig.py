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
from nodes.physics.frames import MovingBody, RobotFrames, TfParams, transform

ROBOT_DESCRIPTION = "/robot_description"


def rig_params(params, robot: RobotModel):
    """The physics parameters as robot ``robot``'s rig reads them, whatever described it:
    every name of the robot from its model (already scoped to the robot), its IMU (site,
    frame and the MuJoCo sensors that read it; none where the model has no IMU), its odom
    frame in its namespace. Base, drive, commanded joints and the frames on its sites and
    cameras are read off the model itself (``Rig``); of ``tf`` only map -> odom counts."""
    imu = params.imu
    sensor = robot.sensor("imu")
    if imu is not None:
        imu = None if sensor is None else imu.model_copy(update={
            "site": sensor.mujoco_name, "frame_id": sensor.link, **dict(sensor.readings)})
    return params.model_copy(update={
        "base_body": robot.base, "base_frame": robot.base_link,
        "odom_frame": robot.frame_prefix + params.odom_frame, "imu": imu, "start": None})


def _msg(t) -> TransformStamped:
    return transform(t.parent, t.child, t.pos, t.quat)


class DescribedRobot:
    """A described robot as robot_state_publisher and joint_state_broadcaster read it from
    its robot model: its movable joints' states under the description's names, and its
    frames (``frames``: the one nodes.physics.frames.RobotFrames every robot has, its links
    for frames)."""

    def __init__(self, model: mujoco.MjModel, robot: RobotModel, odom_frame: str):
        self.model, self.robot = model, robot
        self.state = RobotStateFrames(model, robot, odom_frame)
        self.odom_frame = robot.frame_prefix + odom_frame

    def frames(self, params: TfParams) -> RobotFrames:
        """Its TF: every fixed joint once (/tf_static), map -> odom, odom -> the root link
        (a mobile robot's free joint) and every moving joint per state (/tf): a joint
        between two bodies as the pair of bodies an MJCF robot's moving frames are
        (batched with every robot's by nodes.physics.batch), one with an end on a world
        site (rare: a fixed arm's ``world`` link on a joint that moves) read per robot."""
        data = mujoco.MjData(self.model)
        mujoco.mj_kinematics(self.model, data)  # fixed joints: the same in every state
        moving = [MovingBody(body, parent, parent_link, child_link)
                  for parent_link, child_link, parent, body in self.state.moving_bodies]
        return RobotFrames(params, self.odom_frame, self.robot.base_link,
                           [_msg(t) for t in self.state.static(data)], moving,
                           link_frames=(_OnSites(self.state) if self.state.has_moving_on_sites
                                        else None),
                           publishes_base=self.robot.mobile)

    @property
    def state_joints(self) -> tuple[list[str], list[int], list[int]]:
        """The joints /joint_states carries: names (the description's), qpos and dof
        addresses."""
        joints = self.state.joints
        return [n for n, _, _ in joints], [q for _, q, _ in joints], [d for _, _, d in joints]

    def joint_state(self, data: mujoco.MjData):
        """sensor_msgs/JointState of every movable joint, under the description's names."""
        s = self.state.joint_states(data)
        return m.joint_state(list(s.names), np.array(s.position), np.array(s.velocity),
                             np.array(s.effort))


class _OnSites:
    """The moving joints with an end on a world site, as RobotFrames reads moving links."""

    def __init__(self, state: RobotStateFrames):
        self.state = state
        self.has_moving = True

    def moving(self, data: mujoco.MjData):
        """Their transforms in ``data``'s kinematics."""
        return self.state.moving_on_sites(data)


def robot_description(urdf_text: str) -> String:
    """The /robot_description message: the robot's URDF (expanded, or written from its USD),
    as robot_state_publisher serves it."""
    return String(data=urdf_text)
