"""Pause, step and resume for a realtime node that paces itself (physics publishing /clock),
offered to live clients (rosbridge, Foxglove) with the same names and types as a lockstep
run's services: ``/cosim/pause`` (std_srvs/SetBool) and ``/cosim/step`` (std_srvs/Trigger).
Calls come from the endpoints' threads; the node's loop asks ``may_tick`` before each tick.
"""

from __future__ import annotations

import threading
from typing import Any

from std_srvs.srv import SetBool, Trigger

from plan.timeutil import NS_PER_S, Ns, tick_time_ns
from runtime.live.endpoints import ServiceUnavailable


class RealtimeControl:
    """The pause state of a paced realtime loop (thread-safe)."""

    def __init__(self, tick_ns: Ns):
        self.tick_ns = tick_ns
        self.paused = False
        self.steps = 0
        self.tick = 0
        self._lock = threading.Lock()

    def types(self) -> dict[str, type]:
        """The services offered."""
        return {"/cosim/pause": SetBool, "/cosim/step": Trigger}

    def call(self, name: str, request: Any, timeout_s: float) -> Any:
        """Serve a call at once (the loop picks the new state up before its next tick)."""
        with self._lock:
            if name == "/cosim/pause":
                self.paused = bool(request.data)
                if not self.paused:
                    self.steps = 0
                return SetBool.Response(success=True, message=self._state())
            if name == "/cosim/step":
                if not self.paused:
                    return Trigger.Response(success=False,
                                            message=f"not paused: pause first; {self._state()}")
                self.steps += 1
                return Trigger.Response(success=True,
                                        message=f"stepping one tick; {self._state()}")
        raise ServiceUnavailable(f"no service {name}")

    def may_tick(self, tick: int) -> bool:
        """Before ``tick``: whether it may run now (running, or a step was asked for)."""
        with self._lock:
            self.tick = tick
            if not self.paused:
                return True
            if self.steps:
                self.steps -= 1
                return True
            return False

    def _state(self) -> str:
        word = "paused" if self.paused else "running"
        ns = tick_time_ns(self.tick, self.tick_ns)
        return f"{word} at tick {self.tick} (sim time {ns // NS_PER_S}.{ns % NS_PER_S:09d} s)"
