"""Serialise a ROS message straight to canonical CDR (padding zeroed), without rclpy.

rclpy's ``serialize_message`` converts a message to its C struct field by field through the
Python property of every field and a class-name check of every nested message: a 123-pose
nav_msgs/Path takes about 1.9 ms, and the padding it leaves uninitialised must then be
zeroed (``runtime.cdr.canonical``). This module generates, once per message class,
a Python function that reads the message's slots directly and packs each run of
fixed-size fields with one precompiled ``struct`` format per alignment residue, so the
padding is written as zeros in the same pass. The bytes are exactly
``canonical_cdr(serialize_message(msg))``
(``tests/test_cdr_encode.py`` checks every message type of the standard packages against
rclpy). Types it does not cover (``char``, ``wchar``, ``wstring``, ``long double``) go the
rclpy way.
"""

from __future__ import annotations

import array
import struct
import sys
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np
from rclpy.serialization import serialize_message
from rosidl_parser import definition as d

from runtime.cdr.canonical import LE_HEADER, canonical_cdr
from runtime.cdr.codegen import SourceWriter, Unsupported, code_of, size_of

_ZEROS = tuple(bytes(n) for n in range(8))

Encoder = Callable[[Any], "bytes | None"]


def encode(msg: Any) -> bytes:
    """Canonical CDR bytes of ``msg``: what ``canonical_cdr(serialize_message(msg))`` gives."""
    encoder = encoder_for(type(msg))
    data = encoder(msg) if encoder is not None else None
    if data is None:
        return canonical_cdr(serialize_message(msg), type(msg))
    return data


@cache
def encoder_for(msg_class: type) -> Encoder | None:
    """The generated encoder of a message class, or None when a field type is not covered."""
    if sys.byteorder != "little":  # array and numpy bytes are written as they lie in memory
        return None
    writer = _Writer()
    try:
        writer.message(msg_class, "m")
    except Unsupported:
        return None
    return writer.compile(msg_class.__name__)


def _align_code(align: int) -> str:
    """Statement appending the zero padding that aligns the next field to ``align``."""
    return f"b += Z[(4 - len(b)) & {align - 1}]" if align > 1 else ""


def _primitive_bytes(value: Any, code: str) -> bytes:
    """The packed elements of a primitive array or sequence, in the cheapest way its
    container allows (array.array and numpy arrays as they lie in memory)."""
    if type(value) is array.array and value.typecode == code:
        return value.tobytes()
    if type(value) is np.ndarray and value.dtype == np.dtype("<" + code):
        return value.tobytes()
    if code in "Bc" and isinstance(value, (bytes, bytearray)):
        return bytes(value)
    return struct.pack(f"<{len(value)}{code}", *value)


class _Writer(SourceWriter):
    """Generates the source of one encoder: statements appending to bytearray ``b``."""

    def __init__(self) -> None:
        super().__init__({"Z": _ZEROS, "U32": struct.Struct("<I"),
                          "P": _primitive_bytes, "HEADER": LE_HEADER})
        self.plain = True  # no string or sequence anywhere: rmw sizes it rounded up to 4

    def flush(self) -> None:
        """Pack the pending fixed-size fields with the format of the current residue."""
        if not self.run:
            return
        formats = self.run_formats()
        args = ", ".join(expr for _, _, expr in self.run)
        self.emit(f"b += {formats}[(len(b) - 4) & 7].pack({args})")
        self.run.clear()

    def nested(self, msg_class: type, expr: str) -> None:
        self.message(msg_class, expr)

    def string(self, expr: str) -> None:
        self.plain = False
        self.emit(f"s = {expr}.encode()")
        self.emit(_align_code(4))
        self.emit('b += U32.pack(len(s) + 1); b += s; b += b"\\0"')

    def array(self, slot: d.Array, expr: str) -> None:
        if isinstance(slot.value_type, d.BasicType):
            code = code_of(slot.value_type)
            self.emit(_align_code(min(size_of(slot.value_type), 8)))
            self.emit(f"b += P({expr}, {code!r})")
        else:
            self.each(slot.value_type, expr)

    def sequence(self, slot: d.AbstractSequence, expr: str) -> None:
        self.plain = False
        seq = self.fresh("q")
        self.emit(f"{seq} = {expr}")
        self.emit(_align_code(4))
        self.emit(f"b += U32.pack(len({seq}))")
        if isinstance(slot.value_type, d.BasicType):
            code = code_of(slot.value_type)
            self.emit(f"if not len({seq}):")
            self.emit("    return None")  # see compile(): rmw sizes it apart
            self.emit(_align_code(min(size_of(slot.value_type), 8)))
            self.emit(f"b += P({seq}, {code!r})")
        else:
            self.each(slot.value_type, seq)

    def each(self, element: Any, expr: str) -> None:
        """A loop writing every element of a sequence or array of strings or messages."""
        item = self.fresh("e")
        self.emit(f"for {item} in {expr}:")
        self.depth += 1
        self.field(element, item)
        self.flush()
        self.depth -= 1

    def compile(self, name: str) -> Encoder:
        """The encoder function. rmw_fastrtps gives the bytes the length it estimated:
        for a fixed-size type, the size rounded up to 4; otherwise the exact size, except
        that its estimate aligns the elements of an empty primitive sequence as if there
        were some, so a message with one goes the rclpy way (the generated code returns
        None and ``encode`` falls back)."""
        self.flush()
        if self.plain:
            self.emit("b += Z[-len(b) & 3]")
        return self.function(f"def encode_{name}(m):\n    b = bytearray(HEADER)",
                             "    return bytes(b)", f"encode_{name}", "encoder")
