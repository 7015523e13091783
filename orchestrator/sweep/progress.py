"""The sweep's progress: a bar with runs done, outcomes so far, elapsed time and ETA.

On a terminal, a rich progress bar on stderr, redrawn by the sweep's own loop (no refresh
thread: the local pool forks workers from this process). Elsewhere (a CI log), one line
per finished run. ``--quiet``: nothing.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from orchestrator.sweep.results import FAILED

REDRAW_S = 0.2


class SweepProgress:
    """Counts finished runs and shows them; ``update`` per record, ``poll`` per loop turn."""

    def __init__(self, total: int, skipped: int, quiet: bool):
        self.total = total
        self.counts = {"success": 0, "goal_not_met": 0, "failed": 0}
        self.quiet = quiet
        self.live = not quiet and sys.stderr.isatty()
        self._bar = None
        self._next = 0.0
        if self.live:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._bar = Progress(
                TextColumn("sweep"), BarColumn(), MofNCompleteColumn(),
                TextColumn("{task.fields[outcomes]}"), TimeElapsedColumn(),
                TextColumn("ETA"), TimeRemainingColumn(),
                console=Console(stderr=True), auto_refresh=False, redirect_stdout=False,
                redirect_stderr=False)
            self._task = self._bar.add_task("sweep", total=total, outcomes=self._outcomes())
            self._bar.start()
        elif not quiet and skipped:
            print(f"cosim-sweep: {skipped} finished run(s) skipped (--resume)", file=sys.stderr)

    def update(self, record: dict[str, Any]) -> None:
        """Count a finished run."""
        status = record["status"]
        key = "failed" if status in FAILED else status
        self.counts[key] = self.counts.get(key, 0) + 1
        if self._bar is not None:
            self._bar.update(self._task, advance=1, outcomes=self._outcomes())
            self._redraw(force=True)
        elif not self.quiet:
            done = sum(self.counts.values())
            error = f" {record['error']}" if record.get("error") and status in FAILED else ""
            print(f"[{done}/{self.total}] {record['run_id']}: {status}"
                  f" digest {(record.get('digest') or '-')[:16]}{error}", file=sys.stderr,
                  flush=True)

    def poll(self) -> None:
        """Redraw now and then (the elapsed time and ETA move between runs too)."""
        self._redraw(force=False)

    def _redraw(self, force: bool) -> None:
        now = time.monotonic()
        if self._bar is not None and (force or now >= self._next):
            self._bar.refresh()
            self._next = now + REDRAW_S

    def _outcomes(self) -> str:
        return (f"[green]{self.counts['success']} ok[/] "
                f"[yellow]{self.counts['goal_not_met']} goal missed[/] "
                f"[red]{self.counts['failed']} failed[/]")

    def close(self) -> None:
        """Leave the final bar on the terminal."""
        if self._bar is not None:
            self._bar.stop()
            self._bar = None
