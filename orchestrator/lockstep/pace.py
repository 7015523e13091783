"""A run paced for people: ticks held back to the wall clock (``--real-time-factor R``).

Only the orchestrator's tick loop waits (in-process and the lockstep master alike), before
it starts a tick: tick k no earlier than the start plus its simulated time over R, on the
monotonic clock. Nodes never see the wall clock, so a paced run computes what an unpaced
one does and gives the same digest. A loop slower than R simply runs unpaced (it catches up
after a hiccup: the start is the anchor); a pause moves the anchor (``restart``).
"""

from __future__ import annotations

import time

from plan.options import RunOptions
from plan.timeutil import NS_PER_S


class Pace:
    """When each tick may start: ``origin + time_ns / R`` seconds on the monotonic clock."""

    def __init__(self, factor: float):
        self.factor = factor
        self.origin: float | None = None  # monotonic s at simulated time 0; set by the first tick

    def wait_s(self, time_ns: int) -> float:
        """Seconds until simulated time ``time_ns`` is due (<= 0: it is due). The first call
        (after a ``restart``) anchors the clock: that time is due now."""
        now = time.monotonic()
        offset = time_ns / NS_PER_S / self.factor
        if self.origin is None:
            self.origin = now - offset
        return self.origin + offset - now

    def hold(self, time_ns: int) -> None:
        """Sleep until simulated time ``time_ns`` is due."""
        wait = self.wait_s(time_ns)
        if wait > 0:
            time.sleep(wait)

    def restart(self) -> None:
        """The run was paused or reset: the next tick asked for is due at once."""
        self.origin = None


def pace_of(options: RunOptions) -> Pace | None:
    """The pace a run's options ask for (None: unpaced, as fast as it goes)."""
    return Pace(options.real_time_factor) if options.real_time_factor else None
