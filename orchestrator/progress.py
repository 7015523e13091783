"""The progress display while a run goes: sim time, ticks, real-time factor, ETA.

``update`` runs after every tick, thousands of times a second, so it only compares the
clock with the next redraw time; the display (a rich progress bar on stderr) is refreshed
about ten times a second. Disabled, it does nothing and never imports rich.
"""

from __future__ import annotations

import time

from plan.timeutil import Ns, tick_time_ns

REDRAW_S = 0.1


class Progress:
    """Shows progress on a terminal; silent when quiet or not attached to a terminal."""

    def __init__(self, total_ticks: int, tick_ns: Ns, enabled: bool, console=None):
        self.total_ticks = max(total_ticks, 1)
        self.tick_ns = tick_ns
        self.enabled = enabled
        self._next = 0.0
        self._first: tuple[float, int] | None = None
        self._bar = None
        self._task = None
        self._console = console  # the bar opens at the first tick: its refresh thread must
        # not exist yet when the orchestrator forks the node processes

    def _open(self, console) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, SpinnerColumn, TextColumn
        from rich.progress import Progress as RichProgress

        self._bar = RichProgress(
            SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
            TextColumn("{task.fields[sim]}"), TextColumn("{task.fields[ticks]}"),
            TextColumn("{task.fields[rtf]}"), TextColumn("{task.fields[eta]}"),
            console=console or Console(stderr=True), transient=True,
            refresh_per_second=1 / REDRAW_S)
        self._task = self._bar.add_task("running", total=self.total_ticks,
                                        **self._fields(-1, None))
        self._bar.start()

    def update(self, tick: int) -> None:
        """Called after every finished tick; redraws at most every ``REDRAW_S`` seconds."""
        if not self.enabled:
            return
        now = time.monotonic()
        if now < self._next:
            return
        if self._bar is None:
            self._open(self._console)
        self._next = now + REDRAW_S
        if self._first is None:
            self._first = (now, tick)
        self._bar.update(self._task, completed=tick + 1, description="running",
                         **self._fields(tick, now))

    def _fields(self, tick: int, now: float | None) -> dict[str, str]:
        """The text columns for the last finished tick."""
        total_s = tick_time_ns(self.total_ticks - 1, self.tick_ns) / 1e9
        sim_s = tick_time_ns(max(tick, 0), self.tick_ns) / 1e9
        fields = {"sim": f"sim {sim_s:7.2f} / {total_s:.2f} s",
                  "ticks": f"tick {tick + 1}/{self.total_ticks}", "rtf": "", "eta": ""}
        rate = self._rate(tick, now)
        if rate:
            fields["rtf"] = f"{rate * float(self.tick_ns) / 1e9:6.2f}x real time"
            fields["eta"] = f"ETA {format_s((self.total_ticks - tick - 1) / rate)}"
        return fields

    def _rate(self, tick: int, now: float | None) -> float | None:
        """Ticks per wall-clock second since the first tick was seen."""
        if now is None or self._first is None:
            return None
        t0, k0 = self._first
        if now <= t0 or tick <= k0:
            return None
        return (tick - k0) / (now - t0)

    def close(self) -> None:
        """Remove the display."""
        if self._bar is not None:
            self._bar.stop()
            self._bar = None


def format_s(seconds: float) -> str:
    """'42 s', '3 min 05 s', '1 h 02 min'."""
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"
