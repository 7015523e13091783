"""The progress display while a run goes: sim time, ticks, real-time factor, ETA."""

from __future__ import annotations


class Progress:
    """Shows progress on a terminal; silent when quiet or not attached to a terminal."""

    def __init__(self, total_ticks: int, tick_ns: int, enabled: bool):
        self.total_ticks = total_ticks
        self.tick_ns = tick_ns
        self.enabled = enabled

    def update(self, tick: int) -> None:
        """Called after every finished tick."""

    def close(self) -> None:
        """Remove the display."""
