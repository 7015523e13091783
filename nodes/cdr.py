"""Zero the alignment padding of CDR bytes, so equal messages give equal bytes.

rclpy's ``serialize_message`` leaves the padding between fields uninitialised: two
serialisations of the same message can differ in those bytes, which would make the run
digest (and the recorded bytes) differ between runs. ``canonical_cdr`` walks the
message's layout (from its rosidl type description) and zeroes every padding byte. The
walk skips over arrays of primitives in one step, so images and point clouds cost no more
than a small message.
"""

from __future__ import annotations

import importlib
import struct
from functools import cache

from rosidl_parser import definition as d

_HEADER = 4  # encapsulation header; CDR alignment is relative to its end
_SIZES = {"boolean": 1, "octet": 1, "char": 1, "uint8": 1, "int8": 1, "int16": 2,
          "uint16": 2, "int32": 4, "uint32": 4, "float": 4, "int64": 8, "uint64": 8,
          "double": 8, "long double": 16, "wchar": 2}
_U32 = struct.Struct("<I")


class CdrLayoutError(ValueError):
    """The bytes do not fit the message's layout (a type cosim cannot canonicalise)."""


def canonical_cdr(data: bytes, msg_class: type) -> bytes:
    """``data`` with every padding byte set to zero; raises CdrLayoutError on a mismatch."""
    buf = bytearray(data)
    end = _walk_struct(buf, _HEADER, _plan(msg_class))
    if end > len(buf):
        raise CdrLayoutError(f"{msg_class.__name__}: layout runs past the data")
    buf[end:] = bytes(len(buf) - end)
    return bytes(buf)


@cache
def _plan(msg_class: type) -> tuple:
    """The message's fields as ops: ('p', size) | ('s',) | ('m', plan) | ('a'|'q', op, n)."""
    slots = getattr(msg_class, "SLOT_TYPES", ())
    if not slots:
        return (("p", 1),)  # an empty struct carries one placeholder byte
    return tuple(_op(slot) for slot in slots)


def _op(slot) -> tuple:
    if isinstance(slot, d.BasicType):
        return ("p", _SIZES[slot.typename])
    if isinstance(slot, d.AbstractWString):
        raise CdrLayoutError("wstring fields are not supported")
    if isinstance(slot, d.AbstractString):
        return ("s",)
    if isinstance(slot, d.NamespacedType):
        module = importlib.import_module(".".join(slot.namespaces))
        return ("m", _plan(getattr(module, slot.name)))
    if isinstance(slot, d.Array):
        return ("a", _op(slot.value_type), slot.size)
    if isinstance(slot, d.AbstractSequence):
        return ("q", _op(slot.value_type), 0)
    raise CdrLayoutError(f"unsupported field type {slot!r}")


def _align(buf: bytearray, pos: int, size: int) -> int:
    pad = -(pos - _HEADER) % size
    if pad:
        buf[pos:pos + pad] = bytes(pad)
    return pos + pad


def _walk_struct(buf: bytearray, pos: int, plan: tuple) -> int:
    for op in plan:
        pos = _walk(buf, pos, op)
    return pos


def _walk(buf: bytearray, pos: int, op: tuple) -> int:
    kind = op[0]
    if kind == "p":
        return _align(buf, pos, min(op[1], 8)) + op[1]
    if kind == "s":
        pos = _align(buf, pos, 4)
        return pos + 4 + _U32.unpack_from(buf, pos)[0]
    if kind == "m":
        return _walk_struct(buf, pos, op[1])
    element, count = op[1], op[2]
    if kind == "q":
        pos = _align(buf, pos, 4)
        count = _U32.unpack_from(buf, pos)[0]
        pos += 4
    if element[0] == "p":
        return _align(buf, pos, min(element[1], 8)) + count * element[1] if count else pos
    for _ in range(count):
        pos = _walk(buf, pos, element)
    return pos
