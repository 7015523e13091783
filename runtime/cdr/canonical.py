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
LE_HEADER = b"\x00\x01\x00\x00"  # the encapsulation header of little-endian plain CDR
_SIZES = {"boolean": 1, "octet": 1, "char": 1, "uint8": 1, "int8": 1, "int16": 2,
          "uint16": 2, "int32": 4, "uint32": 4, "float": 4, "int64": 8, "uint64": 8,
          "double": 8, "long double": 16, "wchar": 2}
_U32 = struct.Struct("<I")


class CdrLayoutError(ValueError):
    """The bytes do not fit the message's layout (a type cosim cannot canonicalise)."""


def canonical_cdr(data: bytes, msg_class: type) -> bytes:
    """``data`` with every padding byte set to zero; raises CdrLayoutError on a mismatch."""
    buf = bytearray(data)
    try:
        end = _walk(buf, _HEADER, _plan(msg_class))
    except struct.error as exc:
        raise CdrLayoutError(f"{msg_class.__name__}: layout runs past the data") from exc
    if end > len(buf):
        raise CdrLayoutError(f"{msg_class.__name__}: layout runs past the data")
    buf[end:] = bytes(len(buf) - end)
    return bytes(buf)


@cache
def _plan(msg_class: type) -> tuple:
    """The message's layout as flat ops, nested structs inlined:
    ('b', table) a block of fixed-size fields, ('s',) a string, ('qp', size) a sequence of
    primitives, ('q', ops) a sequence and ('a', ops, n) an array of anything else."""
    ops: list[tuple] = []
    run: list[tuple[int, int]] = []  # (alignment, size) of consecutive fixed-size fields
    _flatten(msg_class, ops, run)
    _close_run(ops, run)
    return tuple(ops)


def _flatten(msg_class: type, ops: list, run: list) -> None:
    slots = getattr(msg_class, "SLOT_TYPES", ())
    if not slots:
        run.append((1, 1))  # an empty struct carries one placeholder byte
    for slot in slots:
        _flatten_slot(slot, ops, run)


def _flatten_slot(slot, ops: list, run: list) -> None:
    if isinstance(slot, d.BasicType):
        size = _SIZES[slot.typename]
        run.append((min(size, 8), size))
    elif isinstance(slot, d.AbstractWString):
        raise CdrLayoutError("wstring fields are not supported")
    elif isinstance(slot, d.AbstractString):
        _close_run(ops, run)
        ops.append(("s",))
    elif isinstance(slot, d.NamespacedType):
        module = importlib.import_module(".".join(slot.namespaces))
        _flatten(getattr(module, slot.name), ops, run)
    elif isinstance(slot, d.Array) and isinstance(slot.value_type, d.BasicType):
        size = _SIZES[slot.value_type.typename]
        run.extend([(min(size, 8), size)] * slot.size)
    elif isinstance(slot, d.Array):
        _close_run(ops, run)
        ops.append(("a", _element_plan(slot.value_type), slot.size))
    elif isinstance(slot, d.AbstractSequence) and isinstance(slot.value_type, d.BasicType):
        _close_run(ops, run)
        ops.append(("qp", _SIZES[slot.value_type.typename]))
    elif isinstance(slot, d.AbstractSequence):
        _close_run(ops, run)
        ops.append(("q", _element_plan(slot.value_type)))
    else:
        raise CdrLayoutError(f"unsupported field type {slot!r}")


def _element_plan(slot) -> tuple:
    ops: list[tuple] = []
    run: list[tuple[int, int]] = []
    _flatten_slot(slot, ops, run)
    _close_run(ops, run)
    return tuple(ops)


def _close_run(ops: list, run: list) -> None:
    """Turn a run of fixed-size fields into one block op: for each start offset modulo 8,
    how far the block reaches and where its padding lies (alignments divide 8)."""
    if not run:
        return
    table = []
    for residue in range(8):
        pos, pads = residue, []
        for align, size in run:
            pad = -pos % align
            if pad:
                pads.append((pos - residue, pad))
            pos += pad + size
        table.append((pos - residue, tuple(pads)))
    ops.append(("b", tuple(table)))
    run.clear()


def _walk(buf: bytearray, pos: int, ops: tuple) -> int:
    for op in ops:
        kind = op[0]
        if kind == "b":
            advance, pads = op[1][(pos - _HEADER) & 7]
            for offset, n in pads:
                buf[pos + offset:pos + offset + n] = bytes(n)
            pos += advance
        elif kind == "s":
            pos = _align(buf, pos, 4)
            pos += 4 + _U32.unpack_from(buf, pos)[0]
        elif kind == "qp":
            pos = _align(buf, pos, 4)
            count = _U32.unpack_from(buf, pos)[0]
            pos += 4
            if count:
                pos = _align(buf, pos, min(op[1], 8)) + count * op[1]
        elif kind == "q":
            pos = _align(buf, pos, 4)
            count = _U32.unpack_from(buf, pos)[0]
            pos += 4
            for _ in range(count):
                pos = _walk(buf, pos, op[1])
        else:  # "a"
            for _ in range(op[2]):
                pos = _walk(buf, pos, op[1])
    return pos


def _align(buf: bytearray, pos: int, size: int) -> int:
    pad = -(pos - _HEADER) % size
    if pad:
        buf[pos:pos + pad] = bytes(pad)
    return pos + pad
