"""ROS 2 interface types by name, and messages from and to plain YAML values (what
rosidl_runtime_py does for ros2cli; that package is not on PyPI)."""

from __future__ import annotations

import array
import importlib
from typing import Any

import yaml

KINDS = ("msg", "srv", "action")


def interface_class(name: str, kind: str) -> type:
    """The class of ``pkg/kind/Name`` or ``pkg/Name`` (``kind``: msg, srv or action);
    ValueError naming the form when it cannot be found."""
    parts = name.strip("/").split("/")
    if len(parts) == 2:
        parts = [parts[0], kind, parts[1]]
    if len(parts) != 3 or parts[1] != kind or not all(parts):
        raise ValueError(f"{name!r} is not a {kind} type: give pkg/{kind}/Name or pkg/Name, "
                         f"e.g. {_EXAMPLES[kind]}")
    package, _, type_name = parts
    try:
        module = importlib.import_module(f"{package}.{kind}")
        return getattr(module, type_name)
    except (ImportError, AttributeError):
        raise ValueError(f"unknown {kind} type {name!r}: no {type_name} in the Python package "
                         f"{package}.{kind}") from None


_EXAMPLES = {"msg": "geometry_msgs/msg/Twist", "srv": "std_srvs/srv/Trigger",
             "action": "simulation_interfaces/action/SimulateSteps"}


def type_name(cls: type) -> str:
    """'pkg/msg/Name' of a message, service or action class."""
    package, kind = cls.__module__.split(".")[:2]
    return f"{package}/{kind}/{cls.__name__}"


def parse_values(text: str | None) -> dict[str, Any]:
    """The YAML mapping of a command line's values ('' or None: no values)."""
    if not text or not text.strip():
        return {}
    try:
        values = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"the values {text!r} are not YAML: {exc}") from None
    if values is None:
        return {}
    if not isinstance(values, dict):
        raise ValueError(f"the values {text!r} are not a YAML mapping such as "
                         "\"{linear: {x: 0.5}}\"")
    return values


def fill(msg: Any, values: dict[str, Any], where: str = "") -> Any:
    """Set ``msg``'s fields from ``values`` (nested mappings for nested messages, lists for
    sequences); ValueError naming the field that does not exist or does not take the value."""
    fields = msg.get_fields_and_field_types()
    for key, value in values.items():
        path = f"{where}{key}"
        if key not in fields:
            raise ValueError(f"{type(msg).__name__} has no field {path!r} "
                             f"(fields: {', '.join(fields)})")
        current = getattr(msg, key)
        if isinstance(value, dict) and hasattr(current, "get_fields_and_field_types"):
            fill(current, value, f"{path}.")
            continue
        if isinstance(value, list) and _is_message_sequence(fields[key]):
            element = _message_class(_element_type(fields[key]))
            items = []
            for i, item in enumerate(value):
                if not isinstance(item, dict):
                    raise ValueError(f"field '{path}[{i}]' ({_element_type(fields[key])}) "
                                     f"cannot take {item!r}: a mapping of its fields is "
                                     "needed")
                items.append(fill(element(), item, f"{path}[{i}]."))
            setattr(msg, key, items)
            continue
        try:
            setattr(msg, key, _coerce(fields[key], value))
        except (AssertionError, TypeError, ValueError) as exc:
            raise ValueError(f"field {path!r} ({fields[key]}) cannot take {value!r}: "
                             f"{exc or 'wrong type'}") from None
    return msg


_FLOATS = {"float", "double", "float32", "float64"}
_INTS = {"int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64", "byte",
         "octet", "char"}


def _coerce(field_type: str, value: Any) -> Any:
    """``value`` as the primitive field type wants it (an int for a float field becomes a
    float: YAML reads 1 as an int); TypeError when it is of another kind (rclpy checks field
    types only when ROS_PYTHON_CHECK_FIELDS=1, so a wrong one would go out on the wire)."""
    base = _element_type(field_type)
    if base != field_type:  # a sequence or array of primitives
        if not isinstance(value, list):
            raise TypeError("a list is needed")
        return [_coerce(base, v) for v in value]
    base = base.split("<=")[0]
    is_int = isinstance(value, int) and not isinstance(value, bool)
    if base in _FLOATS and (is_int or isinstance(value, float)):
        return float(value)
    if base in _INTS and is_int:
        return value
    if base == "boolean" and isinstance(value, bool):
        return value
    if base in ("string", "wstring") and isinstance(value, str):
        return value
    if "/" in base:
        raise TypeError("a mapping of its fields is needed")
    raise TypeError(f"a {base} is needed")


def _is_message_sequence(field_type: str) -> bool:
    """Whether a field type such as 'sequence<geometry_msgs/PoseStamped>' holds messages."""
    return "/" in _element_type(field_type)


def _element_type(field_type: str) -> str:
    """'sequence<pkg/Name, 3>' or 'pkg/Name[4]' -> 'pkg/Name'."""
    if field_type.startswith("sequence<"):
        field_type = field_type[len("sequence<"):-1].split(",")[0]
    return field_type.split("[")[0]


def _message_class(name: str) -> type:
    """The class of 'pkg/Name' as a field type names it."""
    return interface_class(name, "msg")


def to_plain(msg: Any) -> Any:
    """A message as plain values (dicts, lists, numbers, text) in field order, for YAML."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {key: to_plain(getattr(msg, key)) for key in msg.get_fields_and_field_types()}
    if isinstance(msg, list | tuple | array.array):
        return [to_plain(v) for v in msg]
    if hasattr(msg, "tolist"):  # numpy arrays and scalars
        return msg.tolist()
    if isinstance(msg, bytes):
        return list(msg)
    return msg


def to_yaml(msg: Any) -> str:
    """A message as ros2 topic echo prints it: block-style YAML in field order."""
    return yaml.safe_dump(to_plain(msg), default_flow_style=False, sort_keys=False,
                          width=1 << 20).rstrip("\n")
