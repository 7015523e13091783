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
rclpy), empty primitive sequences included: rmw_fastrtps gives the bytes the length its
size estimate says, and the estimate aligns the elements of an empty primitive sequence as
if there were some, so such a message ends in as many zeros as a generated estimator
(``_Estimator``, the same walk as rmw's ``get_serialized_size``) finds. Types it does not
cover (``char``, ``wchar``, ``wstring``, ``long double``) go the rclpy way.
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
from runtime.cdr.codegen import SourceWriter, Unsupported, code_of, run_format, size_of

_ZEROS = tuple(bytes(n) for n in range(8))
_U32 = struct.Struct("<I")

Encoder = Callable[[Any], bytes]


def encode(msg: Any) -> bytes:
    """Canonical CDR bytes of ``msg``: what ``canonical_cdr(serialize_message(msg))`` gives."""
    encoder = encoder_for(type(msg))
    if encoder is None:
        return canonical_cdr(serialize_message(msg), type(msg))
    return encoder(msg)


_STAMP = struct.Struct("<iI")


@cache
def header_first(msg_class: type) -> bool:
    """Whether a message class's first field is a std_msgs/Header."""
    slots = getattr(msg_class, "SLOT_TYPES", ())
    first = slots[0] if slots else None
    return (isinstance(first, d.NamespacedType) and first.name == "Header"
            and list(first.namespaces) == ["std_msgs", "msg"])


class ConstantTails:
    """``encode`` of messages their makers promised never to change but for their header's
    stamp (``nodes.contract.constant_message``): under each key (a node's output topic)
    the last such message is kept with its bytes past the stamp, and while the same object
    comes again only the stamp is written in front of them. What is held is one message
    and its bytes per key, whatever the run's length: a new message (a replan) replaces
    the last. A message whose first field is not a std_msgs/Header (a TFMessage's stamps
    lie in its transforms) is encoded every time."""

    def __init__(self) -> None:
        self._last: dict[Any, tuple[Any, bytes]] = {}  # key -> (message, bytes past stamp)

    def encode(self, key: Any, msg: Any) -> bytes:
        """``encode(msg)``, from the bytes kept under ``key`` when ``msg`` is the message
        kept there."""
        last = self._last.get(key)
        if last is None or last[0] is not msg:
            if not header_first(type(msg)):
                return encode(msg)
            data = encode(msg)
            self._last[key] = (msg, data[len(LE_HEADER) + _STAMP.size:])
            return data
        return stamped(msg._header._stamp, last[1])


def stamped(stamp: Any, tail: bytes) -> bytes:
    """The CDR bytes of a message whose first field is a std_msgs/Header: its
    builtin_interfaces/Time ``stamp`` in front of ``tail``, its bytes past the stamp."""
    return LE_HEADER + _STAMP.pack(stamp._sec, stamp._nanosec) + tail


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
    return writer.compile(msg_class.__name__, msg_class)


def _is_string(slot: Any) -> bool:
    """Whether a field's type is a string (of bytes: wstring is not covered)."""
    return isinstance(slot, d.AbstractString) and not isinstance(slot, d.AbstractWString)


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


_CACHE_SIZE = 4096  # strings and string sequences kept; all are forgotten when it is full
_strings: dict[str, bytes] = {}
_string_seqs: dict[tuple, bytes] = {}


def _string_bytes(text: str) -> bytes:
    """A string field as CDR writes it from a 4-byte boundary: its UTF-8 length with the
    terminating zero, the bytes, the zero. Kept: names and frames come again at every tick."""
    data = _strings.get(text)
    if data is None:
        raw = text.encode()
        data = _U32.pack(len(raw) + 1) + raw + b"\0"
        if len(_strings) >= _CACHE_SIZE:
            _strings.clear()
        _strings[text] = data
    return data


def _string_seq_bytes(seq: Any) -> bytes:
    """A sequence of strings as CDR writes it from a 4-byte boundary (every alignment in it
    is to 4, so the bytes do not depend on where it starts): the count, then each string at
    its 4-byte boundary. Kept by content: joint and interface names repeat at every tick."""
    key = tuple(seq)
    data = _string_seqs.get(key)
    if data is None:
        out = bytearray(_U32.pack(len(key)))
        for text in key:
            out += _ZEROS[-len(out) & 3]
            out += _string_bytes(text)
        data = bytes(out)
        if len(_string_seqs) >= _CACHE_SIZE:
            _string_seqs.clear()
        _string_seqs[key] = data
    return data


_ANY = frozenset(range(8))


def _aligned(residues: frozenset[int], align: int) -> frozenset[int]:
    """The residues (mod 8) after aligning to ``align`` from any of ``residues``."""
    return frozenset((r + (-r % align)) % 8 for r in residues)


def _advanced(residues: frozenset[int], size: int) -> frozenset[int]:
    """The residues (mod 8) after any number of ``size``-byte elements."""
    return frozenset((r + k * size) % 8 for r in residues for k in range(8))


class _Writer(SourceWriter):
    """Generates the source of one encoder: statements appending to bytearray ``b``.

    It follows where the bytes may stand, mod 8 past the header (``res``, the residues
    possible there), so that an alignment already given (after a sequence's count, after
    float64 elements) is not written and a run of fixed-size fields at a known residue is
    packed with that residue's format directly."""

    def __init__(self) -> None:
        super().__init__({"Z": _ZEROS, "U32": _U32, "P": _primitive_bytes,
                          "S": _string_bytes, "SS": _string_seq_bytes, "HEADER": LE_HEADER})
        self.plain = True  # no string or sequence anywhere: rmw sizes it rounded up to 4
        self.empties = False  # a primitive sequence somewhere, which may be empty
        self.res = frozenset({0})

    def align(self, align: int) -> None:
        """Append the zero padding that aligns the next field to ``align``, where needed."""
        if any(r % align for r in self.res):
            self.emit(_align_code(align))
            self.res = _aligned(self.res, align)

    def flush(self) -> None:
        """Pack the pending fixed-size fields with the format of the current residue (the
        one format where every residue it may be at has the same)."""
        if not self.run:
            return
        args = ", ".join(expr for _, _, expr in self.run)
        formats = {run_format(self.run, r) for r in self.res}
        if len(formats) == 1:  # one layout wherever it may start
            packer = self.const(struct.Struct(formats.pop()))
            self.emit(f"b += {packer}.pack({args})")
        else:
            self.emit(f"b += {self.run_formats()}[(len(b) - 4) & 7].pack({args})")
        self.res = frozenset((r + struct.calcsize(run_format(self.run, r))) % 8
                             for r in self.res)
        self.run.clear()

    def nested(self, msg_class: type, expr: str) -> None:
        self.message(msg_class, expr)

    def string(self, expr: str) -> None:
        self.plain = False
        self.align(4)
        self.emit(f"b += S({expr})")
        self.res = _ANY

    def array(self, slot: d.Array, expr: str) -> None:
        if isinstance(slot.value_type, d.BasicType):
            code = code_of(slot.value_type)
            size = size_of(slot.value_type)
            self.align(min(size, 8))
            self.emit(f"b += P({expr}, {code!r})")
            self.res = frozenset((r + slot.size * size) % 8 for r in self.res)
        else:
            self.each(slot.value_type, expr)

    def sequence(self, slot: d.AbstractSequence, expr: str) -> None:
        self.plain = False
        self.align(4)
        if _is_string(slot.value_type):
            self.emit(f"b += SS({expr})")
            self.res = _ANY
            return
        seq = self.fresh("q")
        self.emit(f"{seq} = {expr}")
        self.emit(f"b += U32.pack(len({seq}))")
        self.res = frozenset((r + 4) % 8 for r in self.res)
        if isinstance(slot.value_type, d.BasicType):
            code = code_of(slot.value_type)
            size = size_of(slot.value_type)
            self.empties = True
            counted = self.res
            self.emit(f"if len({seq}):")
            self.depth += 1
            self.align(min(size, 8))
            self.emit(f"b += P({seq}, {code!r})")
            self.depth -= 1
            self.emit("else:")
            self.emit("    x = True")  # see compile(): rmw sizes it apart
            self.res = _advanced(self.res, size) | counted
        else:
            self.each(slot.value_type, seq)

    def each(self, element: Any, expr: str) -> None:
        """A loop writing every element of a sequence or array of strings or messages: its
        body written for every residue it may start at (those before it and those after a
        pass), so it is written again until they stay the same."""
        start, mark, empties = self.res, len(self.lines), self.empties
        while True:
            del self.lines[mark:]
            self.res, self.empties = start, empties
            item = self.fresh("e")
            self.emit(f"for {item} in {expr}:")
            self.depth += 1
            self.field(element, item)
            self.flush()
            self.depth -= 1
            if self.res <= start:
                break
            start = start | self.res
        self.res = start

    def compile(self, name: str, msg_class: type) -> Encoder:
        """The encoder function. rmw_fastrtps gives the bytes the length it estimated:
        for a fixed-size type, the size rounded up to 4; otherwise the exact size, except
        that its estimate aligns the elements of an empty primitive sequence as if there
        were some: where one was met (``x``), the bytes are padded with zeros to what the
        estimator of ``msg_class`` gives."""
        self.flush()
        header = f"def encode_{name}(m):\n    b = bytearray(HEADER)"
        if self.plain:
            self.emit("b += Z[-len(b) & 3]")
        if self.empties:
            header += "\n    x = False"
            size = self.const(estimator_for(msg_class))
            self.emit(f"if x: b += bytes({size}(m) + {len(LE_HEADER)} - len(b))")
        return self.function(header, "    return bytes(b)", f"encode_{name}", "encoder")


def estimator_for(msg_class: type) -> Callable[[Any], int]:
    """A generated function giving what rmw_fastrtps estimates as the serialised size of a
    message of ``msg_class`` (header excluded): every field aligned as it would be written,
    the elements of an empty primitive sequence aligned as if there were some."""
    writer = _Estimator()
    writer.message(msg_class, "m")
    writer.flush()
    name = msg_class.__name__
    return writer.function(f"def size_{name}(m):\n    p = 0", "    return p",
                           f"size_{name}", "size estimator")


def _pad_code(align: int) -> str:
    """Expression of the padding that aligns position ``p`` to ``align``."""
    return f"(-p & {align - 1}) + " if align > 1 else ""


class _Estimator(SourceWriter):
    """Generates the source of one size estimator: statements advancing position ``p``."""

    def __init__(self) -> None:
        super().__init__({"S": _string_bytes, "SS": _string_seq_bytes})

    def flush(self) -> None:
        """Advance over the pending fixed-size fields, by the residue they start at."""
        if not self.run:
            return
        advances = tuple(struct.calcsize(run_format(self.run, residue)) for residue in range(8))
        self.emit(f"p += {self.const(advances)}[p & 7]")
        self.run.clear()

    def nested(self, msg_class: type, expr: str) -> None:
        self.message(msg_class, expr)

    def string(self, expr: str) -> None:
        self.emit(f"p += (-p & 3) + len(S({expr}))")

    def array(self, slot: d.Array, expr: str) -> None:
        if isinstance(slot.value_type, d.BasicType):
            size = size_of(slot.value_type)
            self.emit(f"p += {_pad_code(min(size, 8))}{slot.size * size}")
        else:
            self.each(slot.value_type, expr)

    def sequence(self, slot: d.AbstractSequence, expr: str) -> None:
        if _is_string(slot.value_type):
            self.emit(f"p += (-p & 3) + len(SS({expr}))")
            return
        seq = self.fresh("q")
        self.emit(f"{seq} = {expr}")
        self.emit("p += (-p & 3) + 4")
        if isinstance(slot.value_type, d.BasicType):
            size = size_of(slot.value_type)
            self.emit(f"p += {_pad_code(min(size, 8))}len({seq}) * {size}")
        else:
            self.each(slot.value_type, seq)

    def each(self, element: Any, expr: str) -> None:
        """A loop advancing over every element of a sequence or array of strings or
        messages."""
        item = self.fresh("e")
        self.emit(f"for {item} in {expr}:")
        self.depth += 1
        self.field(element, item)
        self.flush()
        self.depth -= 1
