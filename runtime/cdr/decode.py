"""Read CDR bytes into a ROS message without rclpy's per-field conversion.

The counterpart of ``runtime.cdr.encode``: for each message class a Python function is
generated once that unpacks each run of fixed-size fields with one precompiled ``struct``
format per alignment residue and sets the message's slots directly, building exactly the
objects ``rclpy.serialization.deserialize_message`` builds (floats, ints, bools, ``bytes``
octets, ``array.array`` for numeric sequences, numpy arrays for fixed numeric arrays, lists
for the rest). ``tests/test_cdr_decode.py`` checks every message type of the standard
packages against rclpy, value and type. Types it does not cover go the rclpy way.
"""

from __future__ import annotations

import array
import struct
import sys
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np
from rclpy.serialization import deserialize_message
from rosidl_parser import definition as d

from runtime.cdr.canonical import LE_HEADER
from runtime.cdr.codegen import SourceWriter, Unsupported, code_of, size_of

Decoder = Callable[[bytes], Any]


def decode(data: bytes, msg_class: type) -> Any:
    """The message in ``data``: what ``deserialize_message(data, msg_class)`` gives."""
    decoder = decoder_for(msg_class)
    if decoder is not None and data[:4] == LE_HEADER:
        try:
            return decoder(data)
        except (struct.error, IndexError, ValueError, UnicodeDecodeError):
            pass  # malformed: let rclpy say what is wrong with it
    return deserialize_message(data, msg_class)


@cache
def decoder_for(msg_class: type) -> Decoder | None:
    """The generated decoder of a message class, or None when a field type is not covered."""
    if sys.byteorder != "little":
        return None
    reader = _Reader()
    try:
        root = reader.new_message(msg_class)
        reader.message(msg_class, root)
    except Unsupported:
        return None
    return reader.compile(msg_class.__name__, root)


def _numeric_array(data: bytes, dtype: np.dtype, count: int, pos: int) -> np.ndarray:
    return np.frombuffer(data, dtype, count, pos).copy()


def _numeric_sequence(data: bytes, code: str, start: int, end: int) -> array.array:
    out = array.array(code)
    out.frombytes(data[start:end])
    return out


class _Reader(SourceWriter):
    """Generates the source of one decoder: statements reading bytes ``b`` from offset ``p``."""

    placeholder = "_"

    def __init__(self) -> None:
        super().__init__({"U32": struct.Struct("<I"), "NA": _numeric_array,
                          "NS": _numeric_sequence})

    def align(self, size: int) -> None:
        if size > 1:
            self.emit(f"p += (4 - p) & {size - 1}")

    def flush(self) -> None:
        """Unpack the pending fixed-size fields with the format of the current residue."""
        if not self.run:
            return
        formats = self.run_formats()
        targets = ", ".join(target for _, _, target in self.run)
        self.emit(f"s = {formats}[(p - 4) & 7]")
        self.emit(f"{targets}, = s.unpack_from(b, p)")
        self.emit("p += s.size")
        self.run.clear()

    def new_message(self, msg_class: type) -> str:
        """A variable holding a new, empty instance of ``msg_class`` (no __init__ defaults)."""
        cls = self.const(msg_class)
        var = self.fresh("v")
        self.emit(f"{var} = {cls}.__new__({cls})")
        self.emit(f"{var}._check_fields = {msg_class()._check_fields!r}")
        return var

    def nested(self, msg_class: type, target: str) -> None:
        var = self.new_message(msg_class)
        self.emit(f"{target} = {var}")
        self.message(msg_class, var)

    def string(self, target: str) -> None:
        self.align(4)
        self.emit("n = U32.unpack_from(b, p)[0]")
        self.emit("p += 4 + n")
        self.emit(f"{target} = b[p - n:p - 1].decode()")

    def array(self, slot: d.Array, target: str) -> None:
        element = slot.value_type
        if isinstance(element, d.BasicType):
            if code_of(element) in "?c":
                raise Unsupported("bool or octet array")
            dtype = self.const(np.dtype("<" + code_of(element)))
            self.align(min(size_of(element), 8))
            self.emit(f"{target} = NA(b, {dtype}, {slot.size}, p)")
            self.emit(f"p += {slot.size * size_of(element)}")
        else:
            self.each(element, target, str(slot.size))

    def sequence(self, slot: d.AbstractSequence, target: str) -> None:
        element = slot.value_type
        self.align(4)
        count = self.fresh("n")
        self.emit(f"{count} = U32.unpack_from(b, p)[0]")
        self.emit("p += 4")
        if not isinstance(element, d.BasicType):
            self.each(element, target, count)
            return
        code, size = code_of(element), size_of(element)
        if code == "?":
            raise Unsupported("bool sequence")
        if code == "c":
            self.emit(f"{target} = [b[i:i + 1] for i in range(p, p + {count})]")
            self.emit(f"p += {count}")
            return
        if size > 1:
            self.emit(f"if {count}:")
            self.emit(f"    p += (4 - p) & {min(size, 8) - 1}")
        self.emit(f"{target} = NS(b, {code!r}, p, p + {count} * {size})")
        self.emit(f"p += {count} * {size}")

    def each(self, element: Any, target: str, count: str) -> None:
        """A list of ``count`` strings or messages read one after the other."""
        items = self.fresh("l")
        self.emit(f"{items} = []")
        self.emit(f"for _ in range({count}):")
        self.depth += 1
        item = self.fresh("e")
        self.field(element, item)
        self.flush()
        self.emit(f"{items}.append({item})")
        self.depth -= 1
        self.emit(f"{target} = {items}")

    def compile(self, name: str, root: str) -> Decoder:
        """The decoder function."""
        self.flush()
        return self.function(f"def decode_{name}(b):\n    p = 4", f"    return {root}",
                             f"decode_{name}", "decoder")
