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
``robot_0/controller_manager``); a ``/**: ros__parameters:`` block applies to every node,
a node's own block over it. The parameters of a node's blocks are read by rclpy's own reader
(``rclpy.parameter.parameter_dict_from_yaml_file``: typed as ROS parameters, nested names
flattened to dotted ones, ``/**`` first). That reader matches node names only as written
(``target_nodes`` must equal a key of the file; ``/**/controller_manager`` or
``/robot_0/jtc`` are not found as ``controller_manager`` or ``jtc``, and without
``target_nodes`` it merges every node's parameters into one), so the keys are matched to
node names here and handed to it exactly.

Each controller's parameters are checked against its type's model (the registry's class
``Params``, as generate_parameter_library declares them upstream): a missing or wrong
parameter is a :class:`ControllersFileError` naming the file, the key and what is accepted.
A type cosim does not serve loads without parameters (``ControllerEntry.params`` None):
``ControllersFile.unserved`` names them, and only their activation is refused.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from nodes.ros2_control.interface import ControllerParams
from nodes.ros2_control.registry import controller_class, served_types

MANAGER = "controller_manager"
PARAMS = "ros__parameters"
WILDCARD = "/**"


class ControllersFileError(ValueError):
    """A controllers file cosim cannot serve: the file, the key, the problem, the fix."""

    def __init__(self, file: Path | str, key: str, problem: str, accepted: str):
        self.file, self.key, self.problem, self.accepted = str(file), key, problem, accepted
        super().__init__(f"controllers file {file}: {key}: {problem} Accepted: {accepted}")


@dataclass(frozen=True)
class ControllerEntry:
    """One controller of the file: its name, type and checked parameters (None for a type
    cosim does not serve)."""

    name: str
    type: str
    params: ControllerParams | None

    @property
    def served(self) -> bool:
        """Whether cosim can run its type."""
        return self.params is not None


@dataclass(frozen=True)
class ControllersFile:
    """The controller manager's update rate and its controllers in file order."""

    file: Path
    update_rate: int
    controllers: tuple[ControllerEntry, ...]

    def named(self, name: str) -> ControllerEntry:
        """The controller called ``name``."""
        return next(c for c in self.controllers if c.name == name)

    @property
    def unserved(self) -> tuple[ControllerEntry, ...]:
        """The controllers whose type cosim cannot run (they load; they cannot be active)."""
        return tuple(c for c in self.controllers if not c.served)


def node_name(key: str) -> str:
    """'/**/controller_manager' -> 'controller_manager'; '/**' stays '/**'."""
    key = str(key)
    if key.strip("/") == "**":
        return WILDCARD
    return key.rstrip("/").rsplit("/", 1)[-1]


def read_controllers_file(path: Path | str, *more: Path | str) -> ControllersFile:
    """Read and check a controllers file; ControllersFileError naming what is wrong.
    Several files are merged in order, a later file's parameter over an earlier's, as
    ros2_control_node merges the ``--params-file`` files it is given (and gz_ros2_control
    its plugin's ``<parameters>`` tags). Read once per content: the plan's checks, the
    physics node and the orchestrator's services each ask for the file, and get the
    same reading while each file's bytes are the same; an edited file is read again
    (a sweep, a notebook)."""
    paths = [Path(p) for p in (path, *more)]
    texts = [_text(p) for p in paths]
    key = tuple((str(p.resolve()), hashlib.sha256(t.encode()).hexdigest())
                for p, t in zip(paths, texts, strict=True))
    if key not in _READ:
        if len(_READ) >= _READ_KEPT:
            del _READ[next(iter(_READ))]
        _READ[key] = _read(paths, texts)
    return _READ[key]


_READ: dict[tuple[tuple[str, str], ...], ControllersFile] = {}
_READ_KEPT = 16  # files a process keeps read (a sweep's variants, a swarm's robots)


def _read(paths: list[Path], texts: list[str]) -> ControllersFile:
    """The files' controllers, read and checked (``read_controllers_file``)."""
    path = paths[0]
    files = [(p, _node_keys(p, t)) for p, t in zip(paths, texts, strict=True)]
    manager = _parameters(files, MANAGER)
    if manager is None:
        raise ControllersFileError(_named(paths), MANAGER, "the file has no controller_manager "
                                   "block.", f"{MANAGER}: {{{PARAMS}: {{update_rate: 100, "
                                   "<name>: {type: <package>/<Type>}}}}.")
    rate = manager.get("update_rate", 100)
    if not isinstance(rate, int) or isinstance(rate, bool) or rate <= 0:
        raise ControllersFileError(_named(paths), f"{MANAGER}.{PARAMS}.update_rate",
                                   f"{rate!r} is not a rate.", "a whole number of Hz, e.g. 100.")
    controllers = []
    for name, entry in manager.items():
        if not isinstance(entry, dict) or "type" not in entry:
            continue
        kind = entry["type"]
        cls = controller_class(kind) if isinstance(kind, str) else None
        params = None
        if cls is not None:
            params = check_params(_named(paths), name, cls.Params,
                                  _parameters(files, name) or {})
        controllers.append(ControllerEntry(name, str(kind), params))
    if not controllers:
        raise ControllersFileError(_named(paths), f"{MANAGER}.{PARAMS}", "names no controller.",
                                   "<name>: {type: <package>/<Type>} entries, e.g. "
                                   "joint_state_broadcaster: {type: "
                                   f"{served_types()[0]}}}.")
    return ControllersFile(path, rate, tuple(controllers))


def _named(paths: list[Path]) -> str:
    """The file, or the files merged, as an error names them."""
    return " + ".join(str(p) for p in paths)


def _text(path: Path) -> str:
    """The file's text; ControllersFileError where it cannot be read."""
    try:
        return path.read_text()
    except OSError as exc:
        raise ControllersFileError(path, "(file)", f"cannot be read: {exc.strerror}.",
                                   "the path of a ros2_control controllers YAML file, relative "
                                   "to the scenario.") from None


def _node_keys(path: Path, text: str) -> dict[str, list[str]]:
    """node name -> the file's keys that name it, in file order (``/**`` under itself)."""
    try:
        raw = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ControllersFileError(path, "(file)", f"is not YAML: {exc}",
                                   "a YAML file as ros2_control's controller manager takes it."
                                   ) from None
    if not isinstance(raw, dict):
        raise ControllersFileError(path, "(file)", "holds no mapping of node names.",
                                   f"{MANAGER}: {{{PARAMS}: {{update_rate: 100, ...}}}}.")
    keys: dict[str, list[str]] = {}
    for key, value in raw.items():
        if not isinstance(value, dict) or not isinstance(value.get(PARAMS), dict):
            raise ControllersFileError(path, str(key), f"has no {PARAMS}: mapping.",
                                       f"{key}: {{{PARAMS}: {{...}}}}.")
        keys.setdefault(node_name(key), []).append(key)
    return keys


def _parameters(files: list[tuple[Path, dict[str, list[str]]]], node: str
                ) -> dict[str, Any] | None:
    """The parameters the node ``node`` gets from the files, nested again at their dots
    (None when no block names it), as rclcpp resolves a node's overrides: every file's
    ``/**`` block first, then the node's own blocks (each in file order, a later file's
    parameter over an earlier's), so a node's own block wins over any file's ``/**``."""
    wildcard: dict[str, Any] = {}
    flat: dict[str, Any] = {}
    named = False
    for path, keys in files:
        if WILDCARD in keys:
            wildcard.update(_flat_parameters(path, [WILDCARD]))
        own = keys.get(node)
        if own:
            named = True
            flat.update(_flat_parameters(path, own))
    if not named:
        return None
    flat = {**wildcard, **flat}
    nested: dict[str, Any] = {}
    for dotted, value in flat.items():
        *parents, leaf = dotted.split(".")
        where = nested
        for part in parents:
            where = where.setdefault(part, {})
            if not isinstance(where, dict):
                raise ControllersFileError(_named([p for p, _ in files]),
                                           f"{node}.{PARAMS}.{dotted}", "is both a value and "
                                           "a group of parameters.", "one of the two.")
        where[leaf] = value
    return nested


def _flat_parameters(path: Path, own: list[str]) -> dict[str, Any]:
    """The dotted parameters of the file's blocks ``own`` (in order), by rclpy's reader."""
    # rclpy only here: importing it loads its native library, and an orchestrator that has
    # it loaded may no longer fork its node processes (supervisor.fork_is_safe)
    from rclpy.parameter import parameter_dict_from_yaml_file, parameter_value_to_python

    try:
        flat = parameter_dict_from_yaml_file(str(path), use_wildcard=False, target_nodes=own)
    except (RuntimeError, TypeError, ValueError) as exc:
        raise ControllersFileError(path, own[0], f"is not a ROS parameter block: {exc}",
                                   f"{own[0]}: {{{PARAMS}: {{name: value, ...}}}}.") from None
    return {dotted: parameter_value_to_python(msg.value) for dotted, msg in flat.items()}


def check_params(path: Path | str, name: str, model: type[ControllerParams], raw: dict[str, Any]
                 ) -> ControllerParams:
    """``raw`` checked against the controller type's parameter model."""
    try:
        return model.model_validate(raw)
    except ValidationError as exc:
        error = exc.errors()[0]
        where = ".".join(str(p) for p in error["loc"])
        key = f"{name}.{PARAMS}" + (f".{where}" if where else "")
        field = _field(model, error["loc"])
        accepted = (field.description if field is not None and field.description
                    else "see the controller's parameters in ros2_controllers' documentation")
        problem = _problem(error)
        if isinstance(error.get("input"), str) and error["input"].startswith("["):
            accepted += (" (a list of one type: ROS reads [0, 0.5] as a string, write "
                         "[0.0, 0.5])")
        raise ControllersFileError(path, key, problem, accepted + ".") from None


def _problem(error: dict) -> str:
    kind, message = error["type"], error["msg"]
    if kind == "missing":
        return "is missing."
    if kind == "too_short":
        return "is empty." if error.get("input") in ([], ()) else f"{message}."
    shown = error.get("input")
    return f"{shown!r}: {message[0].lower()}{message[1:]}."


def _field(model, loc):
    """The pydantic field at ``loc`` (nested models followed), or None."""
    for part in loc:
        fields = getattr(model, "model_fields", None)
        if not isinstance(part, str) or fields is None or part not in fields:
            return None
        field = fields[part]
        model = field.annotation
        last = field
    return last if loc else None
