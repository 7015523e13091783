"""What the live endpoints of a multi-process run see: the nodes' own records, read as they grow.

Every node appends what it publishes to ``parts/<node>.rec`` and flushes after each
activation (``runtime.recording``), whatever the transport; the orchestrator's own
participants (the external node, foreign programs' stand-ins) do the same. A thread of the
orchestrator reads the new records every few milliseconds and offers them to the endpoints
with /clock of every tick it saw, so watching costs the nodes and the master nothing: no
extra subscription on any topic, no work on the lockstep's path.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

from plan.timeutil import Ns, tick_time_ns
from runtime.protocol import CLOCK_TOPIC, encode_clock
from runtime.recording import decode_records

log = logging.getLogger("cosim")

POLL_S = 0.01
YIELD_EVERY = 16  # records offered between two yields of the GIL (the master's loop waits)


class PartFollower:
    """Reads one part file's complete records as they are appended (a reset truncates the
    file: reading starts over)."""

    def __init__(self, path: Path, topics: set[str]):
        self.path = path
        self.topics = topics
        self.offset = 0
        self.restarted = False  # set when the file started over (the run was reset)
        # kept open between reads (a reset truncates the same file): a poll that finds
        # nothing new costs one fstat, not an open, seek and close per node
        self._file = None

    def read(self) -> list[tuple[int, str, bytes]]:
        """The records appended since the last read, as (tick, topic, bytes)."""
        if self._file is None:
            try:
                self._file = open(self.path, "rb")  # noqa: SIM115 - closed in close()
            except FileNotFoundError:
                return []
        size = os.fstat(self._file.fileno()).st_size
        if size == self.offset:
            return []
        if size < self.offset:  # truncated by a reset
            self.offset, self.restarted = 0, True
        self._file.seek(self.offset)
        blob = self._file.read(size - self.offset)
        out, pos = [], 0
        for tick, topic, data, end in decode_records(blob):  # a partial last one waits
            if topic not in self.topics or tick < 0:
                # not where a record starts: rewritten after a reset; start over
                self.offset, self.restarted = 0, True
                return out
            out.append((tick, topic, data))
            pos = end
        self.offset += pos
        return out

    def close(self) -> None:
        """Let the file go."""
        if self._file is not None:
            self._file.close()
            self._file = None


class PartsTail:
    """Follows every node's part file in a thread and offers each record (and /clock)."""

    def __init__(self, parts: dict[str, Path], topics: set[str], tick_ns: Ns,
                 offer: Callable[[str, bytes], None]):
        self.followers = [PartFollower(path, topics) for path in parts.values()]
        self.tick_ns = tick_ns
        self.offer = offer
        self.clock_tick = -1
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._follow, name="cosim-live-tail",
                                        daemon=True)

    def start(self) -> None:
        """Start following."""
        self._thread.start()

    def stop(self) -> None:
        """Read what is left, then stop."""
        self._stop.set()
        self._thread.join(timeout=5)

    def _follow(self) -> None:
        while not self._stop.wait(POLL_S):
            self._safely()
        self._safely()  # what was written before the stop
        for follower in self.followers:
            follower.close()

    def _safely(self) -> None:
        try:
            self._once()
        except Exception:  # noqa: BLE001 - watching must never take the run down
            log.exception("live view: reading the nodes' records")

    def _once(self) -> None:
        records = [r for follower in self.followers for r in follower.read()]
        if any(f.restarted for f in self.followers):
            for follower in self.followers:
                follower.restarted = False
            self.clock_tick = -1  # the run was reset: time starts over
        records.sort(key=lambda r: r[0])  # stable: each node's own order within a tick
        for i, (tick, topic, data) in enumerate(records):
            if i % YIELD_EVERY == YIELD_EVERY - 1:
                time.sleep(0)  # let the master's thread have the interpreter
            while self.clock_tick < tick:
                self.clock_tick += 1
                self.offer(CLOCK_TOPIC, encode_clock(tick_time_ns(self.clock_tick,
                                                                  self.tick_ns)))
            self.offer(topic, data)
