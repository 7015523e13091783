"""ROS 2 messages to and from the JSON that rosbridge clients speak (roslibpy, roslibjs).

The rules are rosbridge_server's: a message is an object of its fields, ``uint8``/``char``
arrays are base64 strings (byte strings in CBOR), times are ``{sec, nanosec}``, and a float
that JSON cannot carry (NaN, +-inf: a LaserScan's no-return) is ``null``. Reading a client's
message is strict: an unknown field or a value of the wrong kind is an error naming the
field, and fields left out keep their defaults (as rosbridge does).
"""

from __future__ import annotations

import array
import base64
import importlib
import math
from typing import Any

import numpy as np
from rosidl_parser import definition as idl

from plan.ros_types import ros_type

_BYTES = ("uint8", "char", "octet")


class MessageError(ValueError):
    """A client's message does not fit the type (names the field)."""


def to_json(msg: Any, binary: bool = False) -> dict:
    """A message as a JSON-ready dict (``binary``: keep byte arrays and non-finite floats, for
    CBOR)."""
    out = {}
    for (name, _), kind in zip(msg.get_fields_and_field_types().items(), msg.SLOT_TYPES,
                               strict=True):
        out[name] = _value_to_json(getattr(msg, name), kind, binary)
    return out


def _value_to_json(value: Any, kind, binary: bool) -> Any:
    if isinstance(kind, idl.NamespacedType):
        return to_json(value, binary)
    if isinstance(kind, idl.AbstractNestedType):
        inner = kind.value_type
        if isinstance(inner, idl.BasicType) and inner.typename in _BYTES:
            raw = _as_bytes(value)
            return raw if binary else base64.standard_b64encode(raw).decode("ascii")
        if isinstance(inner, idl.NamespacedType):
            return [to_json(item, binary) for item in value]
        if isinstance(inner, idl.BasicType) and inner.typename in idl.FLOATING_POINT_TYPES:
            items = value.tolist() if isinstance(value, np.ndarray) else list(value)
            return items if binary else [x if math.isfinite(x) else None for x in items]
        return value.tolist() if isinstance(value, np.ndarray) else list(value)
    if isinstance(value, float) and not binary and not math.isfinite(value):
        return None
    if isinstance(value, bytes):  # a single 'byte' (octet) field
        return int.from_bytes(value, "little")
    return value


def _as_bytes(value: Any) -> bytes:
    if isinstance(value, (bytes, bytearray)):
        return bytes(value)
    if isinstance(value, (array.array, np.ndarray)):
        return value.tobytes()
    return b"".join(v if isinstance(v, bytes) else bytes([v]) for v in value)


def from_json(cls: type, value: Any, where: str = "") -> Any:
    """A ``cls`` message from a client's JSON object; MessageError naming the bad field."""
    label = where or ros_type(cls)
    if not isinstance(value, dict):
        raise MessageError(f"{label}: expected a JSON object for {ros_type(cls)}, got "
                           f"{_kind(value)}")
    msg = cls()
    fields = dict(zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES, strict=True))
    for name, given in value.items():
        if name not in fields:
            owner = f"{label} ({ros_type(cls)})" if where else label
            raise MessageError(f"{owner} has no field {name!r} (fields: {', '.join(fields)})")
        path = f"{label}.{name}"
        converted = _value_from_json(fields[name], given, path)
        try:
            setattr(msg, name, converted)
        except (AssertionError, TypeError, ValueError, OverflowError) as exc:
            raise MessageError(f"{path}: {_kind(given)} does not fit {_idl_name(fields[name])}"
                               f" ({exc})") from None
    return msg


def _value_from_json(kind, given: Any, path: str) -> Any:
    if isinstance(kind, idl.NamespacedType):
        return from_json(_class_of(kind), given, path)
    if isinstance(kind, idl.AbstractNestedType):
        inner = kind.value_type
        if isinstance(inner, idl.BasicType) and inner.typename in _BYTES and isinstance(given,
                                                                                       str):
            try:
                raw = base64.standard_b64decode(given)
            except ValueError as exc:
                raise MessageError(f"{path}: not base64 ({exc})") from None
            return array.array("B", raw) if inner.typename != "octet" else [
                bytes([b]) for b in raw]
        if not isinstance(given, list):
            raise MessageError(f"{path}: expected a list for {_idl_name(kind)}, got "
                               f"{_kind(given)}")
        return [_value_from_json(inner, item, f"{path}[{i}]") for i, item in enumerate(given)]
    if isinstance(kind, idl.AbstractGenericString):
        if not isinstance(given, str):
            raise MessageError(f"{path}: expected a string, got {_kind(given)}")
        return given
    if isinstance(kind, idl.BasicType):
        name = kind.typename
        if name == "boolean":
            if not isinstance(given, bool):
                raise MessageError(f"{path}: expected true or false, got {_kind(given)}")
            return given
        if name in idl.FLOATING_POINT_TYPES:
            if given is None:
                return math.nan
            if isinstance(given, bool) or not isinstance(given, (int, float)):
                raise MessageError(f"{path}: expected a number, got {_kind(given)}")
            return float(given)
        if name == "octet":
            if isinstance(given, bool) or not isinstance(given, int):
                raise MessageError(f"{path}: expected an integer, got {_kind(given)}")
            return bytes([given])
        if isinstance(given, bool) or not isinstance(given, int):
            raise MessageError(f"{path}: expected an integer ({name}), got {_kind(given)}")
        return given
    raise MessageError(f"{path}: fields of type {_idl_name(kind)} are not supported")


def _class_of(kind: idl.NamespacedType) -> type:
    return getattr(importlib.import_module(".".join(kind.namespaces)), kind.name)




def _idl_name(kind) -> str:
    if isinstance(kind, idl.NamespacedType):
        return "/".join([*kind.namespaces, kind.name])
    if isinstance(kind, idl.AbstractNestedType):
        return f"{_idl_name(kind.value_type)}[]"
    return getattr(kind, "typename", type(kind).__name__)


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
            list: "a list", dict: "an object"}.get(type(value), type(value).__name__)
