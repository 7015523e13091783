"""Where two messages of one type part: the first field that differs, with both values.

Fields are walked in declaration order, nested messages and arrays recursively, so the
answer is a path like ``poses[3].pose.position.x`` and the two values found there
(``angular.x: 6.91e-310 vs 6.95e-310`` says uninitialised memory at once). Values compare as
their bits do: a digest hashes bytes, so ``0.0`` and ``-0.0`` differ and two NaNs of the same
bits do not. Works on rclpy messages and on the rosbags objects a bag reader gives.
"""

from __future__ import annotations

import array
import dataclasses
import math
import re
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class FieldDifference:
    """The first field where two messages differ: its path and the two values found there
    (for ``what == 'length'`` the two lengths, for ``'type'`` the two type names)."""

    path: str
    first: Any
    second: Any
    what: str = "value"  # value | length | type

    def describe(self) -> str:
        """'angular.x: 6.91e-310 vs 6.95e-310', 'ranges: 360 elements vs 359'."""
        where = self.path or "the message"
        if self.what == "length":
            return f"{where}: {self.first} elements vs {self.second}"
        return f"{where}: {_show(self.first)} vs {_show(self.second)}"


def field_difference(first: Any, second: Any) -> FieldDifference | None:
    """The first field (in declaration order, depth first) where ``first`` and ``second``
    differ; None when every field holds the same bits."""
    return _walk(first, second, "")


def _fields(msg: Any) -> dict[str, str] | None:
    """Field name -> its type as rosidl spells it ('' where unknown) of an rclpy message or
    a rosbags message object; None for a value."""
    get = getattr(type(msg), "get_fields_and_field_types", None)
    if get is not None:
        return dict(get())
    if dataclasses.is_dataclass(msg) and not isinstance(msg, type):
        return {f.name: "" for f in dataclasses.fields(msg)}
    return None


def _is_float32(idl: str) -> bool:
    """'float', 'sequence<float>', 'float[9]': values held as doubles, shown as float32."""
    return re.fullmatch(r"(sequence<)?float(, \d+)?>?(\[\d+\])?", idl) is not None


def _is_sequence(value: Any) -> bool:
    """An array field: a list, tuple, array.array, numpy array or bytes of more than one."""
    if isinstance(value, bytes | bytearray):
        return len(value) != 1
    return isinstance(value, list | tuple | array.array | np.ndarray)


def _walk(a: Any, b: Any, path: str, float32: bool = False) -> FieldDifference | None:
    if type(a) is not type(b) and not (_is_sequence(a) and _is_sequence(b)):
        if not (_number(a) and _number(b)):
            return FieldDifference(path, type(a).__name__, type(b).__name__, "type")
    names = _fields(a)
    if names is not None:
        for name, idl in names.items():
            found = _walk(getattr(a, name), getattr(b, name), f"{path}.{name}" if path else name,
                          _is_float32(idl))
            if found is not None:
                return found
        return None
    if _is_sequence(a):
        if len(a) != len(b):
            return FieldDifference(path, len(a), len(b), "length")
        flat_a = a.ravel() if isinstance(a, np.ndarray) else a
        flat_b = b.ravel() if isinstance(b, np.ndarray) else b
        for i, (x, y) in enumerate(zip(flat_a, flat_b, strict=True)):
            found = _walk(x, y, f"{path}[{i}]", float32)
            if found is not None:
                return found
        return None
    if _same_bits(a, b):
        return None
    if float32 and isinstance(a, float) and isinstance(b, float):
        a, b = np.float32(a), np.float32(b)
    return FieldDifference(path, a, b)


def _number(value: Any) -> bool:
    return isinstance(value, int | float | np.number) and not isinstance(value, bool)


def _same_bits(a: Any, b: Any) -> bool:
    """Equal as a digest sees them: floats by their bits, the rest by value."""
    if isinstance(a, float | np.floating) or isinstance(b, float | np.floating):
        try:
            return struct.pack("<d", float(a)) == struct.pack("<d", float(b))
        except (TypeError, ValueError):
            return False
    return bool(a == b)


def _show(value: Any) -> str:
    """A value as it should read: every float with the digits that tell it apart."""
    if isinstance(value, np.floating):
        return str(value)
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    if isinstance(value, np.integer):
        return str(int(value))
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def serialized_difference(first: bytes, second: bytes, msg_class: type
                          ) -> FieldDifference | None:
    """The first field where two serialised (CDR) messages of ``msg_class`` differ; None
    when they decode to the same bits (equal bytes, or bytes that differ only where no field
    is: padding)."""
    from runtime.cdr.decode import decode

    return field_difference(decode(first, msg_class), decode(second, msg_class))
