"""CDR bytes of a message whose every length is fixed, packed in one ``struct`` call.

A joint state broadcaster publishes the same joints at every update: the names, the counts
and every alignment of its messages are the same each time, only the float values change.
``FixedLayout`` lays such a message out once, as CDR (little endian, XCDR1, which rmw_fastrtps
writes) lays it out from the byte after the stamp of its std_msgs/Header, and makes a function
that packs each update's values into it in one call. Such bytes go to the runtime with their message
(``nodes.contract.encoded_message``); tests compare them with the runtime's encoder and
rclpy's ``serialize_message`` (tests/test_ros2_control_messages.py).
"""

from __future__ import annotations

import struct

_U32 = struct.Struct("<I")


class FixedLayout:
    """A message's bytes past its header's stamp, written field by field in CDR order
    (``string``, ``strings``, ``count``, ``doubles``), then packed with the values of its
    ``doubles`` by the function ``packer_of_runs`` or ``packer_of_columns`` makes."""

    def __init__(self, frame_id: str = ""):
        """Start right after the stamp (alignment counts from the CDR body's start, 8 bytes
        before: the stamp's two 4-byte fields) with the header's ``frame_id``."""
        self._at = 8
        self._constant = bytearray()  # the constant bytes since the last run of doubles
        self._parts: list[bytes | int] = []  # constant bytes, or a run's count of doubles
        self.string(frame_id)

    def _add(self, data: bytes, align: int = 1) -> None:
        pad = bytes(-self._at % align)
        self._constant += pad + data
        self._at += len(pad) + len(data)

    def string(self, text: str) -> FixedLayout:
        """A string: its length with the terminating zero, its UTF-8 bytes, the zero."""
        raw = text.encode()
        self._add(_U32.pack(len(raw) + 1) + raw + b"\0", 4)
        return self

    def strings(self, texts: list[str] | tuple[str, ...]) -> FixedLayout:
        """A sequence of strings: its count, then each string."""
        self.count(len(texts))
        for text in texts:
            self.string(text)
        return self

    def count(self, n: int) -> FixedLayout:
        """A sequence's element count."""
        self._add(_U32.pack(n), 4)
        return self

    def doubles(self, n: int) -> FixedLayout:
        """``n`` float64 values whose value ``pack`` is given (a float64 sequence's
        elements, after its ``count``; none for n = 0)."""
        if n:
            self._add(b"", 8)
            self._parts += [bytes(self._constant), n]
            self._constant.clear()
            self._at += 8 * n
        return self

    @property
    def _runs(self) -> list[int]:
        """The counts of the runs of doubles, in order."""
        return [part for part in self._parts if isinstance(part, int)]

    def _compile(self, arguments: list[str], parameters: str):
        """A function of ``parameters`` packing the constant bytes and ``arguments`` (the
        values of the runs of doubles, in order, as expressions) in one call."""
        parts = [*self._parts, bytes(self._constant)]
        packer = struct.Struct("<" + "".join(
            f"{len(part)}s" if isinstance(part, bytes) else f"{part}d" for part in parts))
        constants = {f"C{i}": part for i, part in enumerate(parts) if isinstance(part, bytes)}
        values = iter(arguments)
        expressions = [f"C{i}" if isinstance(part, bytes) else
                       ", ".join(next(values) for _ in range(part))
                       for i, part in enumerate(parts)]
        source = f"def pack({parameters}):\n    return P({', '.join(expressions)})\n"
        namespace = {"P": packer.pack, **constants}
        exec(compile(source, "<cdr fixed layout>", "exec"), namespace)  # noqa: S102
        return namespace["pack"]

    def packer_of_runs(self):
        """``pack(*runs)``: the bytes with each run of ``doubles`` given its values (a
        sequence of floats each, of the run's length, in the order they were laid out)."""
        runs = self._runs
        arguments = [f"r{k}[{i}]" for k, n in enumerate(runs) for i in range(n)]
        return self._compile(arguments, ", ".join(f"r{k}" for k in range(len(runs))))

    def packer_of_columns(self, columns: int):
        """``pack(*columns)`` for a layout of equal runs of ``columns`` doubles each (a run
        per element of a sequence of messages): value i of every run from ``columns[i]``
        (a sequence with a float per run, in order)."""
        runs = self._runs
        if any(n != columns for n in runs):
            raise ValueError(f"every run of doubles must have {columns} values")
        arguments = [f"c{i}[{k}]" for k in range(len(runs)) for i in range(columns)]
        return self._compile(arguments, ", ".join(f"c{i}" for i in range(columns)))
