"""Several nodes of a scenario in one process: one transport session and one wait.

Which nodes share a process is a deployment choice (the scenario's ``process:`` keys or
``--pack``); it never changes what a node computes, because every runtime still waits for
exactly the samples the schedule names. The process runs one loop: each runtime serves
the ticks it may, then the process waits once on the shared session and every runtime
files what arrived for it.
"""

from __future__ import annotations

import signal
import time

from runtime.lockstep import POLL_NS, STATUS_PERIOD_S, LockstepRuntime
from runtime.protocol import Done, done_status, encode_status
from runtime.shared_transport import SharedTransport

START_CHECKS = 64  # discovery checks of starting runtimes per STATUS_PERIOD_S, at most


class DoneBatch:
    """The activations a packed process's nodes served in one wake-up, reported in one
    ``done`` message (64 lidars each sending their own cost each process ~5 % of its time,
    and the orchestrator a decode per node and tick)."""

    def __init__(self, runtimes: list[LockstepRuntime]):
        self.runtimes = runtimes
        self.done: list[Done] = []

    def add(self, done: list[Done]) -> None:
        """A runtime's activations since its last report, in its tick order."""
        self.done += done

    def flush(self) -> None:
        """Send what was added, if anything (the time counted as the first runtime's)."""
        done, self.done = self.done, []
        if done:
            start = time.perf_counter_ns()
            rt = self.runtimes[0]
            rt.status_pub.publish(encode_status(done_status(done[0].node, done)))
            rt.timing.add("report", start)


class PackedRuntimes:
    """Runs the lockstep runtimes of the nodes packed into this process."""

    def __init__(self, runtimes: list[LockstepRuntime], shared: SharedTransport):
        self.runtimes = runtimes
        self.shared = shared
        self.stop_requested = False
        self._started: set[str] = set()
        self.batch = DoneBatch(runtimes)
        for rt in runtimes:
            rt.batch = self.batch

    def run(self) -> None:
        """Serve every runtime until stopped or every one of them is finished."""
        try:
            while not self.stop_requested:
                now = time.monotonic()
                # a thousand starting nodes checking every topic's matches each period kept
                # the process busy: they share a budget of checks instead
                starting = len(self.runtimes) - len(self._started)
                period = STATUS_PERIOD_S * max(1.0, starting / START_CHECKS)
                for rt in self.runtimes:
                    if rt.name not in self._started:
                        if not rt.clocks:
                            rt.report_start(now, period)
                            continue
                        self._started.add(rt.name)
                        rt.timing.start()
                    rt.serve_announced()
                self.batch.flush()
                if self.stop_requested:
                    break
                self.shared.pump(POLL_NS)
                for rt in self.runtimes:
                    rt.receive(0)
                    rt.check_parent()
                if len(self._started) == len(self.runtimes) and all(
                        rt.finished() for rt in self.runtimes):
                    return
        finally:
            for rt in self.runtimes:
                if rt.timing.started is not None:
                    rt.timing.stop()

    def request_stop(self, *_args) -> None:
        """SIGINT/SIGTERM: every runtime stops after the current wait; a step in progress
        is interrupted (a step that never returns must not hold shutdown up)."""
        self.stop_requested = True
        in_step = False
        for rt in self.runtimes:
            rt.stop_requested = True
            in_step = in_step or rt.in_step
        if in_step:
            raise KeyboardInterrupt

    def report_done(self, *_signal) -> None:
        """SIGALRM during a slow step: every runtime reports what it served before it."""
        for rt in self.runtimes:
            rt.report_done()
        self.batch.flush()


def install_packed_stop_handlers(packed: PackedRuntimes) -> None:
    """SIGINT and SIGTERM end the loop cleanly; SIGALRM reports before a slow step."""
    signal.signal(signal.SIGINT, packed.request_stop)
    signal.signal(signal.SIGTERM, packed.request_stop)
    signal.signal(signal.SIGALRM, packed.report_done)
    for rt in packed.runtimes:
        rt.alarm = True
