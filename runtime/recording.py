"""Per-node recording of published messages, written by the node itself off the lockstep path.

Each node appends what it publishes to ``<run dir>/parts/<node>.rec`` and flushes after
every activation, so a crash keeps everything up to the last finished tick (and tells
which tick a dead node was working on). The
orchestrator merges the parts into a rosbag2 (MCAP) directory at the end of the run.
Record: int64 tick, uint16 topic length, uint32 data length, topic, CDR bytes.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path

from runtime.disk import WriteFailed

_HEAD = struct.Struct("<qHI")


class PartWriter:
    """Appends (tick, topic, bytes) records to one file. A write that fails (a full disk)
    raises WriteFailed naming the file and its file system; the file then keeps every
    complete record before it (a partial last one is ignored by ``read_part``) and takes
    no more."""

    def __init__(self, path: Path):
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.failed = False
        self._file = open(path, "ab", buffering=1 << 20)  # noqa: SIM115 - closed in close()

    def write(self, tick: int, items: list[tuple[str, bytes]]) -> None:
        """Append one activation's outputs and flush them to the OS."""
        if self.failed:
            return
        try:
            for topic, data in items:
                name = topic.encode()
                self._file.write(_HEAD.pack(tick, len(name), len(data)))
                self._file.write(name)
                self._file.write(data)
            self._file.flush()
        except OSError as exc:
            self.failed = True
            raise WriteFailed(self.path, exc, tick) from exc

    def truncate(self) -> None:
        """Forget everything written so far (the run restarted from tick 0)."""
        self._file.flush()
        self._file.seek(0)
        self._file.truncate()

    def close(self) -> None:
        """Flush and close (after a failed write: close, what could not be written is gone)."""
        try:
            self._file.close()
        except OSError as exc:
            if not self.failed:
                self.failed = True
                raise WriteFailed(self.path, exc) from exc


def read_part(path: Path) -> Iterator[tuple[int, str, bytes]]:
    """Every complete record of a part file; a truncated last record is ignored."""
    for tick, topic, data, _ in decode_records(path.read_bytes()):
        yield tick, topic, data


def decode_records(blob: bytes) -> Iterator[tuple[int, str, bytes, int]]:
    """The complete records at the start of ``blob`` (a part file, or what was appended to
    it since a record's end), as (tick, topic, CDR bytes, offset just past the record); an
    incomplete last record (not written yet, or cut short) ends them. The one reader of the
    format ``PartWriter`` writes: the bag's merge and the live view both read through it."""
    pos = 0
    while pos + _HEAD.size <= len(blob):
        tick, nlen, dlen = _HEAD.unpack_from(blob, pos)
        end = pos + _HEAD.size + nlen + dlen
        if end > len(blob):
            return
        topic = blob[pos + _HEAD.size: pos + _HEAD.size + nlen].decode(errors="replace")
        yield tick, topic, blob[end - dlen: end], end
        pos = end
