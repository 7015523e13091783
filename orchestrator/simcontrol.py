"""Simulation control over ROS 2 services while a lockstep run goes.

- ``/cosim/pause`` (std_srvs/SetBool): true pauses before the next tick, false resumes.
- ``/cosim/step`` (std_srvs/Trigger): run exactly one tick while paused.
- ``/cosim/reset`` (std_srvs/Trigger): back to tick 0 with the same seed; the run that
  follows is identical to a fresh one (same digest).

Every reply's message carries the state: ``running`` or ``paused``, the tick and the sim
time. The services live on their own rclpy node and context, so they work whatever the
run's transport; the master polls them between ticks (throttled, off the hot path).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import rclpy
from rclpy.executors import SingleThreadedExecutor
from std_srvs.srv import SetBool, Trigger

POLL_PERIOD_S = 0.02


class SimControl:
    """The services, and the decisions they imply for the master's loop."""

    def __init__(self, tick_ns: int, paused: bool = False, can_reset: str | None = None):
        self.tick_ns = tick_ns
        self.paused = paused
        self.steps = 0
        self.reset_requested = False
        self.cannot_reset = can_reset
        self.tick = 0
        self._next_poll = 0.0
        self._context = rclpy.Context()
        rclpy.init(context=self._context, signal_handler_options=_no_signals())
        self.node = rclpy.create_node("cosim_control", context=self._context,
                                      start_parameter_services=False)
        self.node.create_service(SetBool, "/cosim/pause", self._on_pause)
        self.node.create_service(Trigger, "/cosim/step", self._on_step)
        self.node.create_service(Trigger, "/cosim/reset", self._on_reset)
        self.executor = SingleThreadedExecutor(context=self._context)
        self.executor.add_node(self.node)

    def state(self) -> str:
        """'paused at tick 12 (sim time 0.240000000 s)'."""
        word = "paused" if self.paused else "running"
        ns = self.tick * self.tick_ns
        return f"{word} at tick {self.tick} (sim time {ns // 10**9}.{ns % 10**9:09d} s)"

    def next_action(self, tick: int, idle: Callable[[], None],
                    settle: Callable[[], None] = lambda: None) -> str:
        """Before tick ``tick``: 'tick' to run it, 'reset' to start over; blocks while paused.

        ``settle`` finishes the ticks still in flight; it is called before pausing or
        resetting, so a paused run has really done every tick before ``tick``."""
        self.tick = tick
        now = time.monotonic()
        if now >= self._next_poll:
            self._next_poll = now + POLL_PERIOD_S
            self.executor.spin_once(timeout_sec=0)
        if self.reset_requested or (self.paused and not self.steps):
            settle()
        while True:
            if self.reset_requested:
                self.reset_requested = False
                return "reset"
            if not self.paused:
                return "tick"
            if self.steps:
                self.steps -= 1
                return "tick"
            self.executor.spin_once(timeout_sec=0.05)
            idle()

    def close(self) -> None:
        """Remove the services."""
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self._context)

    def _on_pause(self, request, response):
        # Pausing again only reports the state (steps already asked for still run).
        self.paused = bool(request.data)
        if not self.paused:
            self.steps = 0
        response.success = True
        response.message = self.state()
        return response

    def _on_step(self, request, response):
        response.success = self.paused
        if self.paused:
            self.steps += 1
            response.message = f"stepping one tick; {self.state()}"
        else:
            response.message = f"not paused: pause first; {self.state()}"
        return response

    def _on_reset(self, request, response):
        response.success = self.cannot_reset is None
        if self.cannot_reset is None:
            self.reset_requested = True
            response.message = f"resetting to tick 0 with the same seed; was {self.state()}"
        else:
            response.message = f"cannot reset: {self.cannot_reset}; {self.state()}"
        return response


def _no_signals():
    from rclpy.signals import SignalHandlerOptions

    return SignalHandlerOptions.NO
