"""The user's ros2_control controllers file, read as the controller manager reads it.

The file is the one a ROS 2 user already has::

    controller_manager:
      ros__parameters:
        update_rate: 100
        joint_trajectory_controller:
          type: joint_trajectory_controller/JointTrajectoryController
    joint_trajectory_controller:
      ros__parameters:
        joints: [shoulder_pan, ...]
        command_interfaces: [position]

Node names may carry a namespace or the ``/**`` wildcard (``/**/controller_manager``,
``robot_0/controller_manager``); a ``/**: ros__parameters:`` block applies to every node.
Each controller's parameters are checked against what its Jazzy documentation declares:
a type cosim does not serve, a missing or wrong parameter, is a :class:`ControllersFileError`
naming the file, the key and what is accepted. Parameters declared upstream that cosim reads
but does not act on (PID gains of a position interface, ...) are returned as notes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

JSB = "joint_state_broadcaster/JointStateBroadcaster"
JTC = "joint_trajectory_controller/JointTrajectoryController"
FORWARD = "forward_command_controller/ForwardCommandController"
GROUP_POSITION = "position_controllers/JointGroupPositionController"
GROUP_VELOCITY = "velocity_controllers/JointGroupVelocityController"
DIFF_DRIVE = "diff_drive_controller/DiffDriveController"
SUPPORTED = (JSB, JTC, FORWARD, GROUP_POSITION, GROUP_VELOCITY, DIFF_DRIVE)
MANAGER = "controller_manager"
PARAMS = "ros__parameters"


class ControllersFileError(ValueError):
    """A controllers file cosim cannot serve: the file, the key, the problem, the fix."""

    def __init__(self, file: Path | str, key: str, problem: str, accepted: str):
        self.file, self.key, self.problem, self.accepted = str(file), key, problem, accepted
        super().__init__(f"controllers file {file}: {key}: {problem} Accepted: {accepted}")


@dataclass(frozen=True)
class Tolerance:
    """A joint's tolerances (0: not checked), as ``constraints.<joint>`` gives them."""

    trajectory: float = 0.0
    goal: float = 0.0


@dataclass(frozen=True)
class ControllerSpec:
    """One controller of the file: name, type and its checked parameters."""

    name: str
    type: str
    joints: tuple[str, ...] = ()
    interface: str = "position"  # what it commands (forward controllers, JTC)
    params: dict[str, Any] = field(default_factory=dict)
    tolerances: dict[str, Tolerance] = field(default_factory=dict)


@dataclass(frozen=True)
class ControllersFile:
    """The controller manager's update rate and its controllers in file order."""

    file: Path
    update_rate: int
    controllers: tuple[ControllerSpec, ...]
    notes: tuple[str, ...] = ()

    def named(self, name: str) -> ControllerSpec:
        """The controller called ``name``."""
        return next(c for c in self.controllers if c.name == name)


def _node_name(key: str) -> str:
    """'/**/controller_manager' -> 'controller_manager'; '/**' stays '/**'."""
    key = str(key)
    if key.strip("/") == "**":
        return "/**"
    return key.rstrip("/").rsplit("/", 1)[-1]


def read_controllers_file(path: Path | str) -> ControllersFile:
    """Read and check a controllers file; ControllersFileError naming what is wrong."""
    path = Path(path)
    try:
        raw = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ControllersFileError(path, "(file)", f"cannot be read: {exc.strerror}.",
                                   "the path of a ros2_control controllers YAML file, relative "
                                   "to the scenario.") from None
    except yaml.YAMLError as exc:
        raise ControllersFileError(path, "(file)", f"is not YAML: {exc}",
                                   "a YAML file as ros2_control's controller manager takes it."
                                   ) from None
    if not isinstance(raw, dict):
        raise ControllersFileError(path, "(file)", "holds no mapping of node names.",
                                   f"{MANAGER}: {{{PARAMS}: {{update_rate: 100, ...}}}}.")
    blocks: dict[str, dict[str, Any]] = {}
    common: dict[str, Any] = {}
    for key, value in raw.items():
        name = _node_name(key)
        params = value.get(PARAMS) if isinstance(value, dict) else None
        if not isinstance(params, dict):
            raise ControllersFileError(path, str(key), f"has no {PARAMS}: mapping.",
                                       f"{key}: {{{PARAMS}: {{...}}}}.")
        if name == "/**":
            common.update(params)
        else:
            blocks.setdefault(name, {}).update(params)
    manager = blocks.get(MANAGER)
    if manager is None:
        raise ControllersFileError(path, MANAGER, "the file has no controller_manager block.",
                                   f"{MANAGER}: {{{PARAMS}: {{update_rate: 100, <name>: "
                                   "{type: <package>/<Type>}}}}.")
    rate = manager.get("update_rate", 100)
    if not isinstance(rate, int) or isinstance(rate, bool) or rate <= 0:
        raise ControllersFileError(path, f"{MANAGER}.{PARAMS}.update_rate",
                                   f"{rate!r} is not a rate.", "a whole number of Hz, e.g. 100.")
    notes: list[str] = []
    controllers = []
    for name, entry in manager.items():
        if not isinstance(entry, dict) or "type" not in entry:
            continue
        key = f"{MANAGER}.{PARAMS}.{name}.type"
        kind = entry["type"]
        if kind not in SUPPORTED:
            raise ControllersFileError(path, key, f"controller {name!r} has type {kind!r}, "
                                       "which cosim does not serve.",
                                       "one of " + ", ".join(SUPPORTED) + ".")
        params = {**common, **blocks.get(name, {})}
        controllers.append(_controller(path, name, kind, params, notes))
    if not controllers:
        raise ControllersFileError(path, f"{MANAGER}.{PARAMS}", "names no controller.",
                                   "<name>: {type: <package>/<Type>} entries, e.g. "
                                   f"joint_state_broadcaster: {{type: {JSB}}}.")
    return ControllersFile(path, rate, tuple(controllers), tuple(notes))


def _strings(path: Path, key: str, value: Any, needed: bool) -> tuple[str, ...]:
    if value is None or value == []:
        if needed:
            raise ControllersFileError(path, key, "is missing or empty.",
                                       "a list of joint names, e.g. [joint_1, joint_2].")
        return ()
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ControllersFileError(path, key, f"{value!r} is not a list of names.",
                                   "a list of joint names, e.g. [joint_1, joint_2].")
    if len(set(value)) != len(value):
        raise ControllersFileError(path, key, "names a joint twice.", "unique joint names.")
    return tuple(value)


def _number(path: Path, key: str, value: Any, default: float) -> float:
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ControllersFileError(path, key, f"{value!r} is not a number.", "a number.")
    return float(value)


def _controller(path: Path, name: str, kind: str, params: dict[str, Any],
                notes: list[str]) -> ControllerSpec:
    key = f"{name}.{PARAMS}"
    if kind == JSB:
        joints = _strings(path, f"{key}.joints", params.get("joints"), needed=False)
        return ControllerSpec(name, kind, joints, "", {
            "use_local_topics": bool(params.get("use_local_topics", False)),
            "frame_id": str(params.get("frame_id", "base_link")),
            "publish_dynamic_joint_states": bool(params.get("publish_dynamic_joint_states",
                                                            True))})
    if kind in (FORWARD, GROUP_POSITION, GROUP_VELOCITY):
        joints = _strings(path, f"{key}.joints", params.get("joints"), needed=True)
        interface = {GROUP_POSITION: "position", GROUP_VELOCITY: "velocity"}.get(kind)
        if interface is None:
            interface = params.get("interface_name")
            if interface not in ("position", "velocity", "effort"):
                raise ControllersFileError(path, f"{key}.interface_name", f"{interface!r} is "
                                           "not a command interface.",
                                           "position, velocity or effort.")
        return ControllerSpec(name, kind, joints, interface)
    if kind == JTC:
        return _trajectory_controller(path, name, params, notes)
    return _diff_drive(path, name, params, notes)


def _trajectory_controller(path: Path, name: str, params: dict[str, Any],
                           notes: list[str]) -> ControllerSpec:
    key = f"{name}.{PARAMS}"
    joints = _strings(path, f"{key}.joints", params.get("joints"), needed=True)
    commands = _strings(path, f"{key}.command_interfaces", params.get("command_interfaces"),
                        needed=True)
    if commands != ("position",):
        raise ControllersFileError(path, f"{key}.command_interfaces", f"{list(commands)} is "
                                   "not served: cosim's trajectory controller commands "
                                   "positions.", "[position].")
    method = params.get("interpolation_method", "splines")
    if method not in ("splines", "none"):
        raise ControllersFileError(path, f"{key}.interpolation_method", f"{method!r} is not "
                                   "an interpolation method.", "splines or none.")
    constraints = params.get("constraints") or {}
    if not isinstance(constraints, dict):
        raise ControllersFileError(path, f"{key}.constraints", "is not a mapping.",
                                   "{stopped_velocity_tolerance: 0.01, goal_time: 0.0, "
                                   "<joint>: {trajectory: 0.1, goal: 0.05}}.")
    tolerances = {}
    for joint in joints:
        entry = constraints.get(joint) or {}
        tolerances[joint] = Tolerance(
            _number(path, f"{key}.constraints.{joint}.trajectory", entry.get("trajectory"), 0.0),
            _number(path, f"{key}.constraints.{joint}.goal", entry.get("goal"), 0.0))
    unknown = sorted(set(constraints) - set(joints)
                     - {"stopped_velocity_tolerance", "goal_time", "decelerate_on_cancel"})
    if unknown:
        raise ControllersFileError(path, f"{key}.constraints.{unknown[0]}", "is not a joint of "
                                   "this controller.", "one of " + ", ".join(joints) + ".")
    goal_time = _number(path, f"{key}.constraints.goal_time", constraints.get("goal_time"), 0.0)
    if goal_time < 0:
        raise ControllersFileError(path, f"{key}.constraints.goal_time", "is negative.",
                                   "seconds, 0 or more (0: wait as long as it takes).")
    if params.get("gains"):
        notes.append(f"{name}: gains are not used: cosim's joints take position commands "
                     "(the PID gains of ros2_control apply to velocity or effort interfaces).")
    return ControllerSpec(name, JTC, joints, "position", {
        "interpolate": method == "splines",
        "allow_partial_joints_goal": bool(params.get("allow_partial_joints_goal", False)),
        "allow_nonzero_velocity_at_trajectory_end": bool(
            params.get("allow_nonzero_velocity_at_trajectory_end", False)),
        "stopped_velocity_tolerance": _number(
            path, f"{key}.constraints.stopped_velocity_tolerance",
            constraints.get("stopped_velocity_tolerance"), 0.01),
        "goal_time": goal_time,
        "state_interfaces": list(_strings(path, f"{key}.state_interfaces",
                                          params.get("state_interfaces"), needed=False)
                                 or ("position", "velocity"))}, tolerances)


def _diff_drive(path: Path, name: str, params: dict[str, Any], notes: list[str]
                ) -> ControllerSpec:
    key = f"{name}.{PARAMS}"
    left = _strings(path, f"{key}.left_wheel_names", params.get("left_wheel_names"), True)
    right = _strings(path, f"{key}.right_wheel_names", params.get("right_wheel_names"), True)
    out: dict[str, Any] = {"left": list(left), "right": list(right)}
    for param in ("wheel_separation", "wheel_radius"):
        value = _number(path, f"{key}.{param}", params.get(param), 0.0)
        if value <= 0:
            raise ControllersFileError(path, f"{key}.{param}", f"{value:g} is not a length.",
                                       "metres, more than 0 (the diff drive controller needs "
                                       "it: no default).")
        out[param] = value
    for param in ("wheel_separation_multiplier", "left_wheel_radius_multiplier",
                  "right_wheel_radius_multiplier"):
        out[param] = _number(path, f"{key}.{param}", params.get(param), 1.0)
    out["odom_frame_id"] = str(params.get("odom_frame_id", "odom"))
    out["base_frame_id"] = str(params.get("base_frame_id", "base_link"))
    out["cmd_vel_timeout"] = _number(path, f"{key}.cmd_vel_timeout",
                                     params.get("cmd_vel_timeout"), 0.5)
    out["open_loop"] = bool(params.get("open_loop", False))
    for cov in ("pose_covariance_diagonal", "twist_covariance_diagonal"):
        value = params.get(cov, [0.0] * 6)
        if not isinstance(value, list) or len(value) != 6:
            raise ControllersFileError(path, f"{key}.{cov}", f"{value!r} is not 6 numbers.",
                                       "[xx, yy, zz, rr, pp, yy], e.g. [0.001, 0.001, 0.001, "
                                       "0.001, 0.001, 0.01].")
        out[cov] = [float(v) for v in value]
    for axis, scope in (("linear", "x"), ("angular", "z")):
        block = (params.get(axis) or {}).get(scope) or {}
        for limit in ("max_velocity", "min_velocity", "max_acceleration", "min_acceleration",
                      "max_deceleration", "max_acceleration_reverse",
                      "max_deceleration_reverse"):
            out[f"{axis}.{scope}.{limit}"] = _number(path, f"{key}.{axis}.{scope}.{limit}",
                                                     block.get(limit), math.nan)
        if block.get("max_jerk") is not None or block.get("min_jerk") is not None:
            notes.append(f"{name}: {axis}.{scope} jerk limits are not applied.")
    if params.get("enable_odom_tf", True):
        notes.append(f"{name}: enable_odom_tf: the odom -> base transform on /tf comes from the "
                     "physics node (ground truth), not from this controller's odometry, which "
                     "is published on ~/odom.")
    return ControllerSpec(name, DIFF_DRIVE, left + right, "velocity", out)
