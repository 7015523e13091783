"""The robot model: what every description format (MJCF, USD, URDF or xacro) produces, and what
every node that needs a robot is given instead of finding it through naming conventions.

A scenario with one robot has a swarm of one: the same model, with an empty name and prefix.
In a swarm every robot's model is the description's model scoped to it (``scoped``): the same
links, joints and sensors, every MuJoCo name and TF frame prefixed ``ROBOT/`` (REP-105, as
robot_state_publisher's ``frame_prefix`` does). A robot whose ROS namespace is not its name
(a lone robot of a ``robots:`` section lives at the root) keeps its MuJoCo names and has its
frames in its namespace (``in_namespace``): ``base_link`` at the root.

The model is plain frozen data (names and numbers), so it pickles into forked and spawned nodes
and compares equal across processes.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

CommandInterface = Literal["position", "velocity", "effort"]
JointKind = Literal["revolute", "continuous", "prismatic", "fixed", "floating", "planar"]
SensorKind = Literal["lidar", "camera", "imu"]


@dataclass(frozen=True)
class JointLimits:
    """A joint's limits as URDF's ``<limit>`` gives them (None: not given)."""

    lower: float | None = None
    upper: float | None = None
    effort: float | None = None
    velocity: float | None = None


@dataclass(frozen=True)
class Link:
    """One link of the description: a TF frame. ``body`` is the MuJoCo body that carries it;
    a link fused into its parent (a fixed joint) keeps its frame as a site on the parent body,
    ``site``, so sensor and footprint frames never vanish."""

    name: str
    body: str
    site: str | None = None


@dataclass(frozen=True)
class Joint:
    """One joint between two links, as the description names it."""

    name: str
    kind: JointKind
    parent: str
    child: str
    limits: JointLimits = JointLimits()


@dataclass(frozen=True)
class ActuatorMode:
    """One command interface a joint's actuator can be switched to, as MuJoCo's shortcut
    for it sets the actuator: ``position`` (gain kp, bias 0, -kp, -kv), ``velocity`` (gain
    kv, bias 0, 0, -kv), ``effort`` (a motor: gain 1, no bias); ``ctrlrange`` the commands
    it takes (None: unlimited)."""

    interface: CommandInterface
    kp: float = 0.0
    kv: float = 0.0
    ctrlrange: tuple[float, float] | None = None


@dataclass(frozen=True)
class ActuatedJoint:
    """A joint cosim commands: its MuJoCo joint and actuator, and the command interface the
    actuator is built for. ``modes``: every command interface the robot's ``<ros2_control>``
    block declares for it, the built one first (the hardware switches the actuator to
    another when a controller claiming it is activated); () where it has only ``interface``."""

    joint: str
    actuator: str
    interface: CommandInterface = "position"
    state_interfaces: tuple[str, ...] = ("position", "velocity")
    modes: tuple[ActuatorMode, ...] = ()


@dataclass(frozen=True)
class ControlInterfaces:
    """A joint of the robot's ``<ros2_control>`` block: its MuJoCo joint, the command and
    state interfaces the block declares, and the ``initial_value`` of its state interfaces
    (``(interface, value)``: where a position or velocity starts, as mock_components and
    gz_ros2_control start it)."""

    joint: str
    commands: tuple[str, ...] = ()
    states: tuple[str, ...] = ()
    initial: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class Drive:
    """A differential drive: the two wheel joints and actuators, wheel radius and separation
    in metres."""

    left_joint: str
    right_joint: str
    left_actuator: str
    right_actuator: str
    wheel_radius: float
    wheel_separation: float


@dataclass(frozen=True)
class Sensor:
    """A sensor hung on a link: its kind, the link (TF frame) and the MuJoCo site or camera
    that renders it, and parameters the description carries (a Gazebo ``<sensor>`` tag's
    samples, angles, ranges, update rate), empty when it carries none."""

    kind: SensorKind
    name: str
    link: str
    mujoco_name: str
    params: tuple[tuple[str, float | int | str], ...] = ()
    readings: tuple[tuple[str, str], ...] = ()  # the MuJoCo sensors that read it, by what
    # they read: an IMU's ('gyro', NAME), ('accelerometer', NAME), ('orientation', NAME)


@dataclass(frozen=True)
class CameraLink:
    """A camera's TF frames (REP-103): ``link`` at the MuJoCo camera ``camera`` with body
    axes (x forward, z up), and its colour and depth optical frames (z forward)."""

    camera: str
    link: str
    color_optical: str
    depth_optical: str


@dataclass(frozen=True)
class RobotModel:
    """One robot: its name and prefix, base link, drive, commanded joints, sensors, links and
    joints, and its footprint radius (metres, from its collision geometry). ``base_link`` is
    the base's TF frame, ``base_body`` the MuJoCo body that carries it (the same name unless
    a description says otherwise; empty: ``base_link``)."""

    name: str
    prefix: str
    base_link: str
    mobile: bool
    footprint_radius: float
    drive: Drive | None = None
    actuated: tuple[ActuatedJoint, ...] = ()
    sensors: tuple[Sensor, ...] = ()
    links: tuple[Link, ...] = ()
    joints: tuple[Joint, ...] = ()
    source: str = ""  # the description file it came from
    settings: str = ""  # the settings its reader read ``source`` with (a layout's JSON,
    # descriptions.readers): with ``source``, what its reader gives again from the model
    # alone (its URDF text: ``readers.robot_description_text``)
    base_body: str = ""
    notes: tuple[str, ...] = field(default=(), compare=False)  # what the conversion changed
    reader: str = ""  # the description reader that made it (descriptions.readers: 'urdf',
    # 'usd'); '' for a robot read from a compiled MJCF or USD world by its names
    namespace: str = ""  # its ROS namespace: topics /NS/..., frames NS/...; '' the root
    control: tuple[ControlInterfaces, ...] = ()  # its <ros2_control> block's joints; () none
    site_frames: tuple[Link, ...] = ()  # the TF frames on sites of an MJCF robot (its tool
    # flange, its lidar), in the order /tf_static sends them; a described robot's are links
    camera_frames: tuple[CameraLink, ...] = ()  # the TF frames of an MJCF robot's cameras
    controllers_files: tuple[str, ...] = ()  # the controllers files its description's
    # ros2_control plugin tag names (<gazebo><plugin><parameters>), resolved, in order

    @property
    def frame_prefix(self) -> str:
        """The prefix of its TF frames: 'robot_3/' in its namespace, '' at the root (its
        MuJoCo names' is ``prefix``)."""
        return f"{self.namespace}/" if self.namespace else ""

    def frame(self, mujoco_name: str) -> str:
        """The TF frame of one of its MuJoCo names (a body of an MJCF robot): the MuJoCo
        prefix swapped for the frame prefix."""
        return self.frame_prefix + mujoco_name.removeprefix(self.prefix)

    @property
    def described(self) -> bool:
        """Whether a description reader made it (URDF, xacro, USD): its joints and links
        carry the description's own names (unprefixed on /joint_states), its footprint is
        read from its collision geometry; False for a robot read from an MJCF world."""
        return bool(self.reader)

    def sensor(self, kind: SensorKind, name: str | None = None) -> Sensor | None:
        """The robot's first sensor of ``kind`` (or the one named ``name``), None if absent."""
        for sensor in self.sensors:
            if sensor.kind == kind and (name is None or sensor.name == name):
                return sensor
        return None

    @property
    def base(self) -> str:
        """The MuJoCo body of the base link."""
        return self.base_body or self.base_link

    def scoped(self, robot: str) -> RobotModel:
        """This model as robot ``robot`` of a swarm: every MuJoCo name and frame prefixed
        ``robot/``; the unscoped model (robot '') is returned as it is."""
        if not robot:
            return self
        p = f"{robot}/"
        return replace(
            self, name=robot, prefix=p, namespace=robot, base_link=p + self.base_link,
            base_body=p + self.base_body if self.base_body else "",
            drive=None if self.drive is None else replace(
                self.drive, left_joint=p + self.drive.left_joint,
                right_joint=p + self.drive.right_joint,
                left_actuator=p + self.drive.left_actuator,
                right_actuator=p + self.drive.right_actuator),
            actuated=tuple(replace(a, joint=p + a.joint, actuator=p + a.actuator)
                           for a in self.actuated),
            control=tuple(replace(c, joint=p + c.joint) for c in self.control),
            sensors=tuple(replace(s, link=p + s.link, mujoco_name=p + s.mujoco_name,
                                  readings=tuple((k, p + n) for k, n in s.readings))
                          for s in self.sensors),
            links=tuple(replace(k, name=p + k.name, body=p + k.body,
                                site=None if k.site is None else p + k.site)
                        for k in self.links),
            site_frames=tuple(replace(k, name=p + k.name, body=p + k.body,
                                      site=None if k.site is None else p + k.site)
                              for k in self.site_frames),
            camera_frames=tuple(CameraLink(p + c.camera, p + c.link, p + c.color_optical,
                                           p + c.depth_optical) for c in self.camera_frames),
            joints=tuple(replace(j, name=p + j.name, parent=p + j.parent, child=p + j.child)
                         for j in self.joints))

    def in_namespace(self, namespace: str) -> RobotModel:
        """This (scoped) model with its TF frames in ROS namespace ``namespace`` ('' the
        root: ``base_link``, ``base_scan``) instead of under its name; its MuJoCo names
        (bodies, sites, joints, actuators) keep their prefix."""
        if namespace == self.namespace:
            return self
        old, new = self.frame_prefix, f"{namespace}/" if namespace else ""

        def f(frame: str) -> str:
            return new + frame.removeprefix(old)
        return replace(
            self, namespace=namespace, base_link=f(self.base_link), base_body=self.base,
            sensors=tuple(replace(s, link=f(s.link)) for s in self.sensors),
            links=tuple(replace(k, name=f(k.name)) for k in self.links),
            joints=tuple(replace(j, parent=f(j.parent), child=f(j.child)) for j in self.joints),
            site_frames=tuple(replace(k, name=f(k.name)) for k in self.site_frames),
            camera_frames=tuple(replace(c, link=f(c.link), color_optical=f(c.color_optical),
                                        depth_optical=f(c.depth_optical))
                                for c in self.camera_frames))
