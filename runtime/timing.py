"""Where a node process's run time goes: wall time per part of the lockstep loop.

The runtime adds the time of each part (waiting for and taking messages, reading inputs,
the step, serialising, publishing, recording, hashing, reporting) as it goes: one clock
read per part, off anything that decides an output. At the end of the run the totals are
written next to the node's log, and the orchestrator puts them in the manifest.
"""

from __future__ import annotations

import json
import time
from collections import defaultdict
from pathlib import Path

PARTS = ("wait", "deserialise", "step", "serialise", "publish", "record", "digest", "report")


class TimeSplit:
    """Wall-clock nanoseconds per part, plus the whole run loop's."""

    def __init__(self) -> None:
        self.ns: dict[str, int] = defaultdict(int)
        self.started: int | None = None
        self.ended: int | None = None

    def add(self, part: str, since_ns: int) -> int:
        """Charge the time since ``since_ns`` to ``part``; return now (the next part's start)."""
        now = time.perf_counter_ns()
        self.ns[part] += now - since_ns
        return now

    def span(self, part: str, start_ns: int, end_ns: int) -> int:
        """Charge ``start_ns``..``end_ns`` to ``part``; return ``end_ns``."""
        self.ns[part] += end_ns - start_ns
        return end_ns

    def start(self) -> None:
        """The run loop begins (the first tick may come); what came before does not count."""
        self.ns.clear()
        self.started = time.perf_counter_ns()

    def stop(self) -> None:
        """The run loop has ended."""
        self.ended = time.perf_counter_ns()

    def summary(self) -> dict[str, float]:
        """Seconds per part, the loop's total (``run``) and what no part covers (``other``)."""
        out = {part: round(self.ns.get(part, 0) / 1e9, 4) for part in PARTS}
        if self.started is not None:
            total = (self.ended or time.perf_counter_ns()) - self.started
            out["run"] = round(total / 1e9, 4)
            out["other"] = round(max(total - sum(self.ns.values()), 0) / 1e9, 4)
        return out

    def write(self, path: Path) -> None:
        """Write the summary as JSON (what the manifest's ``time_s`` of the node shows)."""
        path.write_text(json.dumps(self.summary(), indent=1))


def read_summary(path: Path) -> dict[str, float] | None:
    """A node's written summary, or None when the node wrote none (killed, foreign...)."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None
