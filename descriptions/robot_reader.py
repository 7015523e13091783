"""Reading the robot model (``descriptions.robot_model.RobotModel``) out of a compiled MuJoCo
world, once, for every node that needs the robot: MJCF and USD worlds both compile to one
``MjModel``, so one reader serves both formats.

What is read is found by name: cosim's conventions (a root body ``base_link``, wheel joints
``left_wheel_joint`` and ``right_wheel_joint``, sites ``laser`` and ``imu``, a camera
``rgbd``, the sites and cameras TF hangs frames on), each overridable by the scenario's
node parameters that name them (the physics node's ``base_body``, ``wheel_joints``,
``position_joints``, ``tf``, ...; a sensor's ``site`` or ``camera``): ``RobotNames``,
which a node class contributes to with ``description_names``. A sensor, TF site or camera
the world lacks is left out of the model (a node that needs it says so when it is set up);
the base body, and every joint and actuator named, must exist.

In a swarm each robot is read from the swarm world under its prefixed names
(``RobotNames.scoped``), so every number (wheel geometry, footprint) is the one the nodes
measure in that world.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from descriptions.readers import load_robot, reader_for
from descriptions.robot_model import (
    ActuatedJoint,
    CameraLink,
    Drive,
    Joint,
    JointLimits,
    Link,
    RobotModel,
    Sensor,
)
from descriptions.swarm_world import swarm_model
from descriptions.world_geometry import robot_footprint_radius
from descriptions.worldfile import load_world_model

BODY = mujoco.mjtObj.mjOBJ_BODY
JOINT = mujoco.mjtObj.mjOBJ_JOINT
SITE = mujoco.mjtObj.mjOBJ_SITE
CAMERA = mujoco.mjtObj.mjOBJ_CAMERA
ACTUATOR = mujoco.mjtObj.mjOBJ_ACTUATOR
JOINT_KINDS = {int(mujoco.mjtJoint.mjJNT_FREE): "floating", int(mujoco.mjtJoint.mjJNT_BALL):
               "floating", int(mujoco.mjtJoint.mjJNT_SLIDE): "prismatic",
               int(mujoco.mjtJoint.mjJNT_HINGE): "revolute"}


@dataclass(frozen=True)
class RobotNames:
    """The names the robot is read by: cosim's conventions unless the scenario's node
    parameters name others (``StepNode.description_names``). Frames are TF frame names."""

    base_body: str = "base_link"
    base_frame: str = "base_link"
    wheel_joints: tuple[str, str] | None = ("left_wheel_joint", "right_wheel_joint")
    wheel_actuators: tuple[str, str] = ("left_wheel_motor", "right_wheel_motor")
    position_joints: tuple[str, ...] = ("pan_joint", "tilt_joint")
    position_actuators: tuple[str, ...] = ("pan_servo", "tilt_servo")
    laser_site: str = "laser"
    laser_frame: str = "laser"
    imu_site: str = "imu"
    imu_frame: str = "imu_link"
    imu_gyro: str = "imu_gyro"
    imu_accelerometer: str = "imu_accel"
    imu_orientation: str = "imu_quat"
    camera: str = "rgbd"
    camera_frame: str = "camera_color_optical_frame"
    tf_sites: tuple[tuple[str, str], ...] = (("laser", "laser"),)  # (site, frame) on /tf
    tf_cameras: tuple[tuple[str, str, str, str], ...] = (  # (camera, link, colour optical,
        ("rgbd", "camera_link", "camera_color_optical_frame",  # depth optical frame)
         "camera_depth_optical_frame"),)

    @classmethod
    def of(cls, overrides: dict[str, Any]) -> RobotNames:
        """The conventions with ``overrides`` (field -> name; lists become tuples)."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(overrides) - known)
        if unknown:
            raise ValueError(f"no description name {unknown[0]!r}; known: {sorted(known)}")
        return replace(cls(), **{k: tuple(v) if isinstance(v, list) else v
                                 for k, v in overrides.items()})

    def scoped(self, robot: str) -> RobotNames:
        """The names as robot ``robot``'s copy has them in a swarm world: ``robot/NAME``."""
        if not robot:
            return self

        def p(value):
            if value is None:
                return None
            if isinstance(value, tuple):
                return tuple(p(v) for v in value)
            return f"{robot}/{value}"
        return replace(self, **{f.name: p(getattr(self, f.name)) for f in fields(self)})


def read_robot(model: mujoco.MjModel, names: RobotNames = RobotNames(), robot: str = "",
               source: str = "") -> RobotModel:
    """The robot of a compiled world, found by ``names`` (already scoped for a swarm's robot
    ``robot``); a ValueError naming what the world lacks."""
    base = _id(model, BODY, names.base_body, "body")
    free = int(model.body_jntadr[base])
    mobile = free >= 0 and int(model.jnt_type[free]) == int(mujoco.mjtJoint.mjJNT_FREE)
    drive = None
    if names.wheel_joints is not None:
        radius, separation = wheel_geometry(model, *names.wheel_joints)
        for actuator in names.wheel_actuators:
            _id(model, ACTUATOR, actuator, "actuator")
        drive = Drive(*names.wheel_joints, *names.wheel_actuators, radius, separation)
    if len(names.position_actuators) != len(names.position_joints):
        raise ValueError(f"{len(names.position_actuators)} position actuators for "
                         f"{len(names.position_joints)} position joints")
    actuated = []
    for joint, actuator in zip(names.position_joints, names.position_actuators, strict=True):
        _id(model, JOINT, joint, "joint")
        _id(model, ACTUATOR, actuator, "actuator")
        actuated.append(ActuatedJoint(joint, actuator, "position"))
    root = int(model.body_rootid[base])
    bodies = np.flatnonzero(model.body_rootid == root).tolist()  # in array code: once a robot
    sensors = []
    laser = mujoco.mj_name2id(model, SITE, names.laser_site)
    if laser >= 0:
        sensors.append(Sensor("lidar", "lidar", names.laser_frame, names.laser_site))
    imu = mujoco.mj_name2id(model, SITE, names.imu_site)
    if imu >= 0:
        sensors.append(Sensor("imu", "imu", names.imu_frame, names.imu_site, readings=(
            ("gyro", names.imu_gyro), ("accelerometer", names.imu_accelerometer),
            ("orientation", names.imu_orientation))))
    camera = mujoco.mj_name2id(model, CAMERA, names.camera)
    if camera >= 0:
        sensors.append(Sensor("camera", "camera", names.camera_frame, names.camera))
    links = [Link(model.body(b).name, model.body(b).name) for b in bodies]
    links += [Link(s.link, model.body(int(model.site_bodyid[i])).name, s.mujoco_name)
              for s, i in zip([s for s in sensors if s.kind != "camera"],
                              [i for i in (laser, imu) if i >= 0], strict=True)]
    joints = []
    # the joints of its bodies, in array code: a loop over every joint of a thousand
    # robots' world, once a robot, was a second of the swarm's load
    for j in np.flatnonzero(model.body_rootid[model.jnt_bodyid] == root).tolist():
        child = int(model.jnt_bodyid[j])
        if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_FREE):
            continue
        limits = JointLimits()
        if model.jnt_limited[j]:
            limits = JointLimits(float(model.jnt_range[j, 0]), float(model.jnt_range[j, 1]))
        kind = JOINT_KINDS[int(model.jnt_type[j])]
        if kind == "revolute" and not model.jnt_limited[j]:
            kind = "continuous"
        joints.append(Joint(model.joint(j).name, kind,
                            model.body(int(model.body_parentid[child])).name,
                            model.body(child).name, limits))
    # the frames TF hangs on its sites and cameras (the world check names those it lacks)
    site_frames = [Link(frame, model.body(int(model.site_bodyid[i])).name, site)
                   for site, frame in names.tf_sites
                   if (i := mujoco.mj_name2id(model, SITE, site)) >= 0]
    cameras = [CameraLink(*c) for c in names.tf_cameras
               if mujoco.mj_name2id(model, CAMERA, c[0]) >= 0]
    return RobotModel(
        name=robot, prefix=f"{robot}/" if robot else "", namespace=robot,
        base_link=names.base_frame,
        mobile=mobile, footprint_radius=robot_footprint_radius(model, names.base_body),
        drive=drive, actuated=tuple(actuated), sensors=tuple(sensors), links=tuple(links),
        joints=tuple(joints), source=source, base_body=names.base_body,
        site_frames=tuple(site_frames), camera_frames=tuple(cameras))


def wheel_geometry(model: mujoco.MjModel, left_joint: str, right_joint: str
                   ) -> tuple[float, float]:
    """(wheel radius, wheel separation) read from the wheel joints' bodies and their geoms."""
    radii, ys = [], []
    for name in (left_joint, right_joint):
        j = _id(model, JOINT, name, "joint")
        body = model.jnt_bodyid[j]
        geoms = np.flatnonzero(model.geom_bodyid == body)
        if geoms.size == 0:
            raise ValueError(f"wheel joint {name!r} moves a body without a geom")
        radii.append(float(model.geom_size[geoms[0], 0]))
        ys.append(float(model.body_pos[body, 1]))
    return 0.5 * (radii[0] + radii[1]), abs(ys[0] - ys[1])


@functools.lru_cache(maxsize=8)
def world_robots(world: Path, layout, names: RobotNames) -> tuple[RobotModel, ...]:
    """Every robot of a scenario's world, read once per process: the one robot of the world
    (an unnamed swarm of one) or, with a swarm's ``layout`` (``plan.robots.RobotsLayout``),
    each robot of the swarm world under its prefixed names, its frames in its namespace.
    None in a world without the base body (a world of sensors alone)."""
    if layout is None:
        model = load_world_model(world)
        if mujoco.mj_name2id(model, BODY, names.base_body) < 0:
            return ()
        return (read_robot(model, names, source=str(world)),)
    # the swarm world with every robot (those that enter later too), asked of the cache
    # once: its key hashes the whole layout, a thousand robots at a thousand robots
    swarm = functools.cache(lambda: swarm_model(Path(world), layout.everyone))
    return tuple(_layout_robot(layout, swarm, names, r).in_namespace(layout.namespace_of(r))
                 for r in layout.names)


def _layout_robot(layout, swarm: Callable[[], mujoco.MjModel], names: RobotNames, name: str
                  ) -> RobotModel:
    """Robot ``name`` of a swarm: a described one from its own model (links, sensors,
    drive), an MJCF one as the swarm world with every robot (``swarm()``) has it (robots
    that enter later too); each from its own description (an event's robot may have
    another)."""
    description, settings = layout.source_of(name)
    if reader_for(description).described:
        return load_robot(description, settings).model.scoped(name)
    return read_robot(swarm(), names.scoped(name), name, str(description))


def described_robot(layout, name: str) -> RobotModel | None:
    """Robot ``name`` of a swarm's ``layout`` as ``world_robots`` gives it, where a
    description reader made its model (it needs no names to be read); None for an MJCF
    robot."""
    description, settings = layout.source_of(name)
    if not reader_for(description).described:
        return None
    return (load_robot(description, settings).model.scoped(name)
            .in_namespace(layout.namespace_of(name)))


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str, what: str) -> int:
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise ValueError(f"the world has no {what} named {name!r}")
    return i
