"""A URDF or xacro robot description loaded as a cosim robot: the expanded URDF, the MuJoCo
MjSpec with cosim's actuators and sensors added, and the :class:`RobotModel`.

``load_urdf(path, options)`` is the one entry point; the run (every node) and
``cosim-describe`` call it the same way. What the scenario may set is :class:`UrdfOptions`.

Actuators cosim adds (their gains settable through ``UrdfOptions.gains``, keyed by a joint
name or by ``wheel``, ``position``, ``velocity``, ``effort``):

- each drive wheel: a velocity actuator ``JOINT_velocity`` (kv), force limited by the
  joint's ``<limit effort>``;
- each commanded joint, by its first command interface (from ``<ros2_control>``, else the
  scenario's ``interfaces``): ``position`` a position servo ``JOINT_position`` (kp, kv)
  over the joint's ``<limit lower upper>``, ``velocity`` a velocity actuator
  ``JOINT_velocity`` (kv) within ``<limit velocity>``, ``effort`` a motor ``JOINT_effort``
  within ``<limit effort>`` (the ``min``/``max`` params of the block's command interface
  narrow the range: the hardware clamps a command to it, ``MujocoSystem.write``). A joint
  whose block declares several of them keeps one actuator, and every declared interface
  as a mode of it (``ActuatedJoint.modes``, the same gains and ranges: a velocity mode's kv
  is the joint's ``kv``, else ``velocity``'s, default 10): the hardware switches the
  actuator's mode when a controller claiming another interface of the joint is activated;
- the ``initial_value`` params of a joint's position and velocity state interfaces, where
  the joint starts (``RobotModel.control``; physics sets them at reset).

Sensors: a lidar and an IMU read the site of their link (an IMU gets MuJoCo gyro,
accelerometer and framequat sensors ``LINK_gyro``, ``LINK_accel``, ``LINK_quat``), a camera
is a MuJoCo camera named as its link, looking along the link's +x (a Gazebo camera's
convention) or, for an optical frame (REP-103, a link named ``*optical*``), along its +z.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import mujoco
import numpy as np

from descriptions import urdf_geometry as geo
from descriptions.description_error import DescriptionError
from descriptions.packages import PackageNotFound, PackageResolver
from descriptions.robot_model import (
    ActuatedJoint,
    ActuatorMode,
    ControlInterfaces,
    Drive,
    Joint,
    JointLimits,
    Link,
    RobotModel,
    Sensor,
)
from descriptions.urdf_parse import Urdf, parse_urdf
from descriptions.urdf_to_mjcf import COLLISION_GROUP, convert
from descriptions.xacro_expand import expand

INTERFACES = ("position", "velocity", "effort")
INITIAL = ("position", "velocity")  # the state interfaces whose initial_value cosim sets
DEFAULT_GAINS = {"wheel": {"kv": 2.0}, "position": {"kp": 60.0, "kv": 6.0},
                 "velocity": {"kv": 10.0}, "effort": {}}
SENSOR_KINDS = ("lidar", "camera", "imu")
BODY_CAMERA = (0.5, -0.5, -0.5, 0.5)  # looks along +x, image up +z
OPTICAL_CAMERA = (0.0, 1.0, 0.0, 0.0)  # looks along +z, image down +y (REP-103)


@dataclass(frozen=True)
class UrdfOptions:
    """What a scenario says about a URDF robot: xacro args, the packages map, whether the
    base is free (a mobile robot) or fixed to the world ('auto': free when it has a drive),
    the two drive wheel joints (left, right) and, optionally, the drive's numbers, sensors
    as kind -> link, command interfaces for joints outside ``<ros2_control>``, and gains."""

    args: Mapping[str, str] = field(default_factory=dict)
    packages: Mapping[str, str] = field(default_factory=dict)
    base: Literal["auto", "free", "fixed"] = "auto"
    wheels: tuple[str, str] | None = None
    wheel_radius: float | None = None
    wheel_separation: float | None = None
    sensors: Mapping[str, str] = field(default_factory=dict)
    interfaces: Mapping[str, str] = field(default_factory=dict)
    gains: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    env: Mapping[str, str] | None = None  # AMENT_PREFIX_PATH, ROS_PACKAGE_PATH (os.environ)


@dataclass
class LoadedUrdf:
    """A loaded description: the expanded URDF text (what /robot_description carries), the
    MjSpec of the robot alone (actuators and sensors added), the parsed URDF, the robot
    model and the notes on what the conversion changed."""

    urdf_text: str
    spec: mujoco.MjSpec
    urdf: Urdf
    model: RobotModel
    notes: list[str]

    def mjcf(self) -> str:
        """The robot as MJCF text (absolute mesh paths), for the nodes to compile."""
        return self.spec.to_xml()


def load_urdf(path: Path | str, options: UrdfOptions | None = None) -> LoadedUrdf:
    """Expand, convert and describe ``path``; DescriptionError on anything wrong."""
    options = options or UrdfOptions()
    path = Path(path).resolve()
    description = str(path)
    resolver = PackageResolver(dict(options.packages), options.env)
    expanded = expand(path, options.args, resolver)
    urdf = parse_urdf(expanded.urdf, description)
    wheels = _check_wheels(urdf, description, options.wheels)
    free = options.base == "free" or (options.base == "auto" and wheels is not None)
    if free and urdf.root == "world":
        raise DescriptionError(description, "the root link is 'world': the description fixes "
                               "the robot to the world, so it cannot be a mobile robot",
                               link="world", fix="drop the world link and its joint, or use "
                               "base: fixed")
    base_link = _base_link(urdf, description)
    converted = convert(urdf, expanded.urdf, description, resolver, path.parent, free)
    notes = [f"xacro: {w}" for w in expanded.warnings] + converted.notes
    spec = converted.spec
    actuated = _arm_actuators(spec, urdf, description, options, wheels, notes)
    if wheels is not None:
        for joint in wheels:
            cj = urdf.control.get(joint)
            _add_wheel(spec, urdf, joint, options.gains,
                       cj.limits.get("velocity", (None, None)) if cj else (None, None))
    sensors = _sensors(spec, urdf, description, options.sensors, notes)
    try:
        model = spec.compile()
    except ValueError as exc:
        raise DescriptionError(description, f"MuJoCo does not compile it: {exc}",
                               fix="see MuJoCo's message") from None
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    drive = None if wheels is None else _drive(model, data, wheels, options, description, notes)
    collision = [g for g in range(model.ngeom) if model.geom_group[g] == COLLISION_GROUP]
    root_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, base_link)
    robot = RobotModel(
        name="", prefix="", base_link=base_link, mobile=free,
        footprint_radius=round(geo.footprint_radius(model, data, root_id, collision), 6),
        drive=drive, actuated=tuple(actuated), sensors=tuple(sensors),
        # the link 'world' is no body: MuJoCo's world body holds the robot, and the link's
        # frame is a site where the robot is placed (urdf_to_mjcf.WORLD_SITE)
        links=tuple(Link(name, name, name) for name in urdf.links),
        joints=tuple(Joint(j.name, j.kind, j.parent, j.child,
                           JointLimits(j.lower, j.upper, j.effort, j.velocity))
                     for j in urdf.joints.values()),
        source=description, notes=tuple(notes), reader="urdf",
        control=tuple(ControlInterfaces(name, cj.commands, cj.states,
                                        tuple((k, v) for k, v in cj.initial.items()
                                              if k in INITIAL))
                      for name, cj in urdf.control.items()),
        controllers_files=_controllers_files(urdf.controllers_files, resolver, path.parent))
    return LoadedUrdf(expanded.urdf, spec, urdf, robot, notes)


def _controllers_files(given: list[str], resolver: PackageResolver, base: Path
                       ) -> tuple[str, ...]:
    """The ros2_control plugin's ``<parameters>`` files as paths: ``$(find PKG)`` (left by a
    plain .urdf, which xacro did not expand) and ``package://PKG/`` through the packages, a
    relative path from the description's folder; a text naming an unknown package stays as
    it is (the scenario's check says the file is not there)."""
    out = []
    for text in given:
        try:
            found = re.sub(r"\$\(find\s+([^)\s]+)\s*\)",
                           lambda m: str(resolver.find(m[1])), text)
            out.append(str(resolver.resolve_uri(found, base).resolve()))
        except PackageNotFound:
            out.append(text)
    return tuple(out)


def _base_link(urdf: Urdf, description: str) -> str:
    """The robot's base link: its root link, or, where the root is the link ``world`` (how
    UR, Franka and most arm descriptions fix the arm where it stands), the link the world
    holds. DescriptionError when the world holds nothing or more than one link."""
    if urdf.root != "world":
        return urdf.root
    held = urdf.children("world")
    if len(held) != 1:
        raise DescriptionError(
            description, f"the root link 'world' holds {len(held)} links "
            f"({', '.join(j.child for j in held) or 'none'}): cosim places one robot base",
            link="world", fix="one joint from 'world' to the robot's base link")
    return held[0].child


def guess_wheels(urdf: Urdf) -> tuple[str, str] | None:
    """Two turning joints named like wheels, one 'left' and one 'right' (for
    cosim-describe when none are named); None when there is no such pair."""
    turning = [j.name for j in urdf.joints.values()
               if j.kind in ("continuous", "revolute") and "wheel" in j.name.lower()]
    left = [n for n in turning if "left" in n.lower()]
    right = [n for n in turning if "right" in n.lower()]
    return (left[0], right[0]) if len(left) == 1 and len(right) == 1 else None


def _check_wheels(urdf: Urdf, description: str, wheels: tuple[str, str] | None
                  ) -> tuple[str, str] | None:
    if wheels is None:
        return None
    if len(wheels) != 2 or wheels[0] == wheels[1]:
        raise DescriptionError(description, f"wheels {list(wheels)} are not two joints",
                               fix="name the left and the right wheel joint")
    turning = [j.name for j in urdf.joints.values() if j.kind in ("continuous", "revolute")]
    for name in wheels:
        joint = urdf.joints.get(name)
        if joint is None:
            raise DescriptionError(description, "the wheel joint is not in the description",
                                   joint=name, fix=f"one of its turning joints: {turning}")
        if joint.kind not in ("continuous", "revolute"):
            raise DescriptionError(description, f"the wheel joint is {joint.kind}: it does "
                                   "not turn", joint=name,
                                   fix=f"one of its turning joints: {turning}")
    return wheels[0], wheels[1]


def _gain(gains: Mapping[str, Mapping[str, float]], joint: str, kind: str, key: str) -> float:
    for source in (gains.get(joint, {}), gains.get(kind, {}), DEFAULT_GAINS[kind]):
        if key in source:
            return float(source[key])
    return 0.0


def _range(lo: float | None, hi: float | None) -> tuple[float, float] | None:
    return None if lo is None or hi is None or lo >= hi else (lo, hi)


def _add_wheel(spec: mujoco.MjSpec, urdf: Urdf, joint: str,
               gains: Mapping[str, Mapping[str, float]],
               limits: tuple[float | None, float | None]) -> None:
    act = spec.add_actuator(name=f"{joint}_velocity", target=joint,
                            trntype=mujoco.mjtTrn.mjTRN_JOINT)
    act.set_to_velocity(kv=_gain(gains, joint, "wheel", "kv"))
    narrowed = _range(*limits)
    if narrowed is not None:  # the block's velocity min/max: the speeds the wheel takes
        act.ctrllimited, act.ctrlrange = mujoco.mjtLimited.mjLIMITED_TRUE, list(narrowed)
    effort = urdf.joints[joint].effort
    if effort:
        act.forcelimited, act.forcerange = mujoco.mjtLimited.mjLIMITED_TRUE, [-effort, effort]


def _arm_actuators(spec: mujoco.MjSpec, urdf: Urdf, description: str, options: UrdfOptions,
                   wheels: tuple[str, str] | None, notes: list[str]) -> list[ActuatedJoint]:
    wanted: dict[str, tuple[tuple[str, ...], tuple[str, ...],
                            Mapping[str, tuple[float | None, float | None]]]] = {}
    for name, cj in urdf.control.items():
        if name not in urdf.joints:
            raise DescriptionError(description, "<ros2_control> names a joint that is not in "
                                   "the description", joint=name, fix="name an existing joint")
        if wheels and name in wheels:
            if cj.commands and cj.commands[0] != "velocity":
                notes.append(f"wheel {name!r}: <ros2_control> commands {cj.commands[0]}; cosim "
                             "drives the wheels by velocity")
            continue
        usable = [c for c in cj.commands if c in INTERFACES]
        if not usable:
            notes.append(f"joint {name!r}: no position, velocity or effort command interface "
                         f"in <ros2_control> ({list(cj.commands)}): not commanded")
            continue
        if len(usable) > 1:
            notes.append(f"joint {name!r}: <ros2_control> offers {list(cj.commands)}: several "
                         f"command interfaces: the actuator ({usable[0]} at the start) "
                         "switches mode when a controller claims another")
        dropped = [c for c in cj.commands if c not in INTERFACES]
        if dropped and len(cj.commands) > 1:
            notes.append(f"joint {name!r}: command interfaces {dropped} are not realised "
                         "(cosim realises position, velocity and effort)")
        wanted[name] = (tuple(dict.fromkeys(usable)), cj.states or ("position", "velocity"),
                        cj.limits)
    for name, states in urdf.control_sensors.items():
        notes.append(f"<ros2_control> sensor {name!r} ({', '.join(states)}): not simulated, "
                     "no state interfaces (list_hardware_interfaces omits them)")
    for name, interface in options.interfaces.items():
        if name not in urdf.joints or urdf.joints[name].kind == "fixed":
            raise DescriptionError(description, "the joint given an interface is not a "
                                   "moving joint of the description", joint=name,
                                   fix="name a revolute, continuous or prismatic joint")
        if interface not in INTERFACES:
            raise DescriptionError(description, f"interface {interface!r} is not one of "
                                   f"{INTERFACES}", joint=name, fix="position, velocity or effort")
        wanted[name] = ((interface,), ("position", "velocity"), {})
    return [_add_arm_actuator(spec, urdf, name, *spec_, options.gains)
            for name, spec_ in wanted.items()]


def _mode(urdf: Urdf, name: str, interface: str, cmin: float | None, cmax: float | None,
          gains: Mapping[str, Mapping[str, float]]) -> ActuatorMode:
    """Joint ``name``'s actuator as ``interface`` commands it: gains and command range."""
    joint = urdf.joints[name]
    kp = kv = 0.0
    if interface == "position":
        kp, kv = _gain(gains, name, interface, "kp"), _gain(gains, name, interface, "kv")
        limits = _range(joint.lower, joint.upper) if joint.kind != "continuous" else None
    elif interface == "velocity":
        kv = _gain(gains, name, interface, "kv")
        limits = None if not joint.velocity else (-joint.velocity, joint.velocity)
    else:
        limits = None if not joint.effort else (-joint.effort, joint.effort)
    narrowed = _range(cmin, cmax)
    if narrowed is not None:
        limits = narrowed if limits is None else (max(limits[0], narrowed[0]),
                                                  min(limits[1], narrowed[1]))
    return ActuatorMode(interface, kp, kv, limits)  # type: ignore[arg-type]


def _add_arm_actuator(spec: mujoco.MjSpec, urdf: Urdf, name: str, interfaces: tuple[str, ...],
                      states: tuple[str, ...],
                      ranges: Mapping[str, tuple[float | None, float | None]],
                      gains: Mapping[str, Mapping[str, float]]) -> ActuatedJoint:
    joint = urdf.joints[name]
    modes = tuple(_mode(urdf, name, i, *ranges.get(i, (None, None)), gains)
                  for i in interfaces)
    first = modes[0]
    interface = first.interface
    act = spec.add_actuator(name=f"{name}_{interface}", target=name,
                            trntype=mujoco.mjtTrn.mjTRN_JOINT)
    if interface == "position":
        act.set_to_position(kp=first.kp, kv=first.kv)
    elif interface == "velocity":
        act.set_to_velocity(kv=first.kv)
    else:
        act.set_to_motor()
    if first.ctrlrange is not None:
        act.ctrllimited, act.ctrlrange = mujoco.mjtLimited.mjLIMITED_TRUE, list(first.ctrlrange)
    if joint.effort and (interface != "effort" or len(modes) > 1):  # a servo mode's bound
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-joint.effort, joint.effort]
    return ActuatedJoint(name, f"{name}_{interface}", interface, tuple(states),
                         modes if len(modes) > 1 else ())


def _sensors(spec: mujoco.MjSpec, urdf: Urdf, description: str, named: Mapping[str, str],
             notes: list[str]) -> list[Sensor]:
    found: dict[tuple[str, str], Sensor] = {}
    for gz in urdf.sensors:
        if gz.kind is None:
            notes.append(f"Gazebo sensor {gz.name!r} ({gz.type}) on link {gz.link!r}: a kind "
                         "cosim does not simulate, dropped")
            continue
        found[(gz.kind, gz.link)] = Sensor(gz.kind, gz.name, gz.link, gz.link,
                                           tuple(sorted(gz.params.items())))
    for kind, link in named.items():
        if kind not in SENSOR_KINDS:
            raise DescriptionError(description, f"sensor kind {kind!r} is not one of "
                                   f"{SENSOR_KINDS}", fix="lidar, camera or imu")
        if link not in urdf.links:
            raise DescriptionError(description, f"the {kind} is put on a link that is not in "
                                   "the description", link=link,
                                   fix=f"one of its links: {list(urdf.links)}")
        found.setdefault((kind, link), Sensor(kind, kind, link, link))
    for key, sensor in list(found.items()):
        if sensor.kind == "imu":
            readings = []
            for reads, suffix, kind in (
                    ("gyro", "gyro", mujoco.mjtSensor.mjSENS_GYRO),
                    ("accelerometer", "accel", mujoco.mjtSensor.mjSENS_ACCELEROMETER),
                    ("orientation", "quat", mujoco.mjtSensor.mjSENS_FRAMEQUAT)):
                spec.add_sensor(name=f"{sensor.link}_{suffix}", type=kind,
                                objtype=mujoco.mjtObj.mjOBJ_SITE, objname=sensor.link)
                readings.append((reads, f"{sensor.link}_{suffix}"))
            found[key] = replace(sensor, readings=tuple(readings))
        elif sensor.kind == "camera":
            params = dict(sensor.params)
            optical = "optical" in sensor.link
            cam = spec.body(sensor.link).add_camera(
                name=sensor.link, quat=list(OPTICAL_CAMERA if optical else BODY_CAMERA))
            hfov = float(params.get("horizontal_fov", math.radians(60) * 4 / 3))
            w, h = float(params.get("width", 4)), float(params.get("height", 3))
            cam.fovy = math.degrees(2 * math.atan(math.tan(hfov / 2) * h / w))
    return sorted(found.values(), key=lambda s: (SENSOR_KINDS.index(s.kind), s.link))


def _drive(model: mujoco.MjModel, data: mujoco.MjData, wheels: tuple[str, str],
           options: UrdfOptions, description: str, notes: list[str]) -> Drive:
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, w) for w in wheels]
    geoms = [[g for g in range(model.ngeom) if model.geom_bodyid[g] == model.jnt_bodyid[j]
              and model.geom_group[g] == COLLISION_GROUP] for j in ids]
    radius = options.wheel_radius
    if radius is None:
        radii = [geo.wheel_radius(model, data, j, g) for j, g in zip(ids, geoms, strict=True)]
        if min(radii) <= 0:
            raise DescriptionError(description,
                                   "a wheel link has no collision geometry to read its "
                                   "radius from", joint=wheels[radii.index(min(radii))],
                                   fix="give the wheel a <collision>, or the scenario's "
                                       "wheel_radius")
        if abs(radii[0] - radii[1]) > 1e-3:
            notes.append(f"wheel radii differ ({radii[0]:.4f}, {radii[1]:.4f} m): their mean "
                         "is used")
        radius = float(np.mean(radii))
    separation = options.wheel_separation
    if separation is None:
        separation = geo.wheel_separation(model, data, ids[0], ids[1], geoms[0], geoms[1])
    return Drive(wheels[0], wheels[1], f"{wheels[0]}_velocity", f"{wheels[1]}_velocity",
                 round(radius, 6), round(separation, 6))
