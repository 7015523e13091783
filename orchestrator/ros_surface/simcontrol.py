"""How a run is controlled between ticks: play, pause, step, stop and reset.

Requests come from any thread (the ROS 2 servers of ``orchestrator.ros_surface.sim_services``); the
lockstep master takes them before each tick (``next_action``) and tells what it did
(``tick_decided`` per tick, ``reset_done``, ``finished``). Requests that wait for the run (a
step of N ticks, a reset, a stop) block their caller, never the master. No ROS here.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

from plan.timeutil import NS_PER_S, Ns, tick_time_ns

PLAYING, PAUSED, STOPPED = "playing", "paused", "stopped"
POLL_S = 0.05
SETTLE_WAIT_S = 60.0  # how long a step waits for the ticks in flight when a pause begins

Observer = Callable[[int, dict], None]
"""Called by the master with each decided tick and its reports {node: Done} (keep it short)."""


@dataclass
class Outcome:
    """The answer to a request: whether it was done, and the state in words."""

    ok: bool
    message: str
    code: str = ""  # why not: 'state' (wrong state for it), 'ended', 'reset', 'refused'


class RunControl:
    """The requests, and what the master has done, shared between threads."""

    def __init__(self, tick_ns: Ns, paused: bool = False, cannot_reset: str | None = None):
        self.tick_ns = tick_ns
        self.cannot_reset = cannot_reset
        self.state = PAUSED if paused else PLAYING
        self.boundary = 0  # the next tick to run
        self.decided = -1  # the last tick every node that may not trail has finished
        self.settled: int | None = None  # the boundary the master waits at, nothing in flight
        self.epoch = 0  # resets done
        self.ended: str | None = None  # why the tick loop ended
        self.steps = 0  # ticks still to hand to the master while paused
        self.observers: list[Observer] = []
        self.reset_listeners: list[Callable[[], None]] = []  # master thread, after a reset
        self.robot_requests: list = []  # robots clients bring in or take out, not admitted
        self._cond = threading.Condition()
        self._stepping = False
        self._reset_wanted = False
        self._stop_wanted = False

    def where(self) -> str:
        """'paused at tick 12 (sim time 0.240000000 s)': the state and the next tick."""
        return f"{self.state} at {self.at()}"

    def at(self) -> str:
        """'tick 12 (sim time 0.240000000 s)': the next tick to run."""
        ns = tick_time_ns(self.boundary, self.tick_ns)
        return f"tick {self.boundary} (sim time {ns // NS_PER_S}.{ns % NS_PER_S:09d} s)"

    # -- the master's side ------------------------------------------------------------------

    def request_robot(self, request) -> None:
        """A robot a client brings in or takes out: the lockstep admits it at the next tick
        boundary where it can (``LockstepMaster._admit_robots``); ``request`` has ``robot``,
        ``opens`` and ``commit(tick)``."""
        with self._cond:
            self.robot_requests.append(request)
            self._cond.notify_all()

    def take_robot_requests(self) -> list:
        """The robot requests waiting, taken."""
        with self._cond:
            taken, self.robot_requests = self.robot_requests, []
        return taken

    def next_action(self, tick: int, idle: Callable[[], None],
                    settle: Callable[[], None] = lambda: None) -> str:
        """Before tick ``tick``: 'tick' to run it, 'reset' to start over, 'stop' to end the
        run here; blocks while paused, calling ``idle``. ``settle`` finishes the ticks in
        flight: a paused run has done every tick before ``tick``."""
        with self._cond:
            self.boundary = tick
            must_settle = (self._reset_wanted or self._stop_wanted
                           or (self.state == PAUSED and not self.steps))
        if must_settle:
            settle()
        while True:
            with self._cond:
                action = self._choose(tick)
                if action is None:
                    self._cond.wait(POLL_S)  # a request wakes it at once
                    action = self._choose(tick)
            if action is not None:
                return action
            idle()

    def _choose(self, tick: int) -> str | None:
        if self._stop_wanted:
            return "stop"
        if self._reset_wanted:
            self._reset_wanted, self.settled = False, None
            return "reset"
        if self.state == PLAYING or self.steps:
            self.steps = max(self.steps - 1, 0) if self.state == PAUSED else 0
            self.settled = None
            return "tick"
        if self.settled != tick:
            self.settled = tick
            self._cond.notify_all()
        return None

    def tick_decided(self, tick: int, reports: dict) -> None:
        """Every node that may not trail has finished ``tick`` (in tick order)."""
        for observer in self.observers:
            observer(tick, reports)
        with self._cond:
            self.decided = tick
            self._cond.notify_all()

    def reset_done(self) -> None:
        """The nodes are back at tick 0."""
        for listener in self.reset_listeners:
            listener()
        with self._cond:
            self.epoch += 1
            self.boundary, self.decided, self.settled = 0, -1, None
            self._cond.notify_all()

    def finished(self, why: str) -> None:
        """The tick loop ended (or failed): nothing more will run."""
        with self._cond:
            if self.ended is None:
                self.ended = why
            self.state = STOPPED
            self._cond.notify_all()

    # -- the requests -----------------------------------------------------------------------

    def pause(self) -> Outcome:
        """Pause before the next tick (steps already asked for still run)."""
        with self._cond:
            if self.ended is not None:
                return Outcome(False, f"the run has ended: {self.ended}", "ended")
            if self.state == PAUSED:
                return Outcome(False, f"already {self.where()}", "state")
            self.state = PAUSED
            self._cond.notify_all()
            return Outcome(True, f"pausing before {self.at()} or, with ticks in flight, "
                           "right after them")

    def play(self) -> Outcome:
        """Run on."""
        with self._cond:
            if self.ended is not None:
                return Outcome(False, f"the run has ended: {self.ended}", "ended")
            if self.state == PLAYING:
                return Outcome(False, f"already {self.where()}", "state")
            self.state, self.steps = PLAYING, 0
            self._cond.notify_all()
            return Outcome(True, f"playing from {self.at()}")

    def add_step(self) -> Outcome:
        """One more tick while paused, without waiting for it (the std_srvs /cosim/step)."""
        with self._cond:
            if self.ended is not None:
                return Outcome(False, f"the run has ended: {self.ended}", "ended")
            if self.state != PAUSED:
                return Outcome(False, "not paused", "state")
            self.steps += 1
            self._cond.notify_all()
            return Outcome(True, "stepping one tick")

    def request_reset(self) -> Outcome:
        """Ask for a reset without waiting for it (the std_srvs /cosim/reset)."""
        with self._cond:
            if self.cannot_reset is not None:
                return Outcome(False, f"cannot reset: {self.cannot_reset}", "refused")
            if self.ended is not None:
                return Outcome(False, f"the run has ended: {self.ended}", "ended")
            self._reset_wanted, self.steps = True, 0  # steps asked for later run after it
            self._cond.notify_all()
            return Outcome(True, "resetting to tick 0 with the same seed")

    def stop(self, timeout_s: float = 60.0) -> Outcome:
        """End the run at the next tick boundary, once the ticks in flight are done; wait
        until the tick loop has ended."""
        with self._cond:
            if self.ended is not None:
                return Outcome(False, f"the run has ended: {self.ended}", "ended")
            self._stop_wanted = True
            self._cond.notify_all()
            self._cond.wait_for(lambda: self.ended is not None, timeout_s)
            if self.ended is None:
                return Outcome(False, "the run did not stop in time", "refused")
            return Outcome(True, f"stopped: {self.ended}")

    def reset(self, timeout_s: float = 120.0) -> Outcome:
        """Back to tick 0 with the same seed (state unchanged); wait until it is done."""
        with self._cond:
            if self.cannot_reset is not None:
                return Outcome(False, f"cannot reset: {self.cannot_reset}", "refused")
            if self.ended is not None:
                return Outcome(False, f"the run has ended: {self.ended}", "ended")
            epoch = self.epoch
            self._reset_wanted, self.steps = True, 0
            self._cond.notify_all()
        if self.wait_reset(epoch, timeout_s):
            return Outcome(True, f"reset to tick 0; {self.where()}")
        return Outcome(False, f"the run ended before the reset: {self.ended}", "ended")

    def wait_reset(self, epoch: int, timeout_s: float) -> bool:
        """Wait until a reset after ``epoch`` is done (True) or the run is over (False)."""
        with self._cond:
            self._cond.wait_for(lambda: self.epoch > epoch or self.ended is not None, timeout_s)
            return self.epoch > epoch

    def step(self, n: int, on_step: Callable[[int], None] | None = None,
             cancelled: Callable[[], bool] = lambda: False) -> Outcome:
        """Run ``n`` ticks while paused and wait until every node has done them (back at the
        paused boundary). ``on_step(done)`` is called as each tick is decided (from this
        thread); ``cancelled()`` is polled: then no further tick starts."""
        with self._cond:
            problem = self._cannot_step()
            if problem:
                return problem
            self._stepping = True
            self._cond.wait_for(lambda: self.settled is not None or self.ended is not None
                                or self.state != PAUSED, SETTLE_WAIT_S)
        try:
            return self._run_steps(n, on_step or (lambda done: None), cancelled)
        finally:
            with self._cond:
                self._stepping = False

    def _cannot_step(self) -> Outcome | None:
        if self.ended is not None:
            return Outcome(False, f"the run has ended: {self.ended}", "ended")
        if self.state != PAUSED:
            return Outcome(False, f"not paused: pause first; {self.where()}", "state")
        if self._stepping:
            return Outcome(False, f"already stepping; {self.where()}", "state")
        return None

    def _run_steps(self, n: int, on_step: Callable[[int], None],
                   cancelled: Callable[[], bool]) -> Outcome:
        with self._cond:
            if self.settled is None:
                return Outcome(False, f"not paused: {self.where()}", "state")
            start, epoch = self.settled, self.epoch
            target = start + n
            self.steps += n
            self._cond.notify_all()
        told = 0
        stop = False
        while True:
            with self._cond:
                self._cond.wait(POLL_S)
                done = min(max(self.decided - start + 1, 0), n)
                ended, reset = self.ended, self.epoch != epoch
                settled, state = self.settled, self.state
                if not stop and cancelled():
                    stop, self.steps = True, 0
            for count in range(told + 1, done + 1):
                on_step(count)
            told = max(told, done)
            if reset:
                return Outcome(False, f"the run was reset after {told} of {n} step(s)", "reset")
            if ended is not None:
                if done == n:
                    return Outcome(True, f"{n} step(s) done; then the run ended: {ended}")
                return Outcome(False, f"the run ended after {told} of {n} step(s): {ended}",
                               "ended")
            if stop and settled is not None and settled >= start:
                return Outcome(False, f"cancelled after {settled - start} of {n} step(s); "
                               f"{self.where()}", "cancelled")
            if done == n and ((settled is not None and settled >= target) or state != PAUSED):
                return Outcome(True, f"{n} step(s) done; {self.where()}")
