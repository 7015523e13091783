"""Action goals from the live endpoints (a rosbridge client's send_action_goal), served by the
run's own action servers' callbacks, without a round trip through DDS.

A ``LocalGoal`` stands in for rclpy's ServerGoalHandle: the server's execute callback reads
its request, publishes feedback and ends it (succeed, abort, canceled) as it does a ROS 2
client's goal; the goal callback and the cancel callback run as rclpy would run them. So a
goal from a live client acts on the run exactly as one from ``ros2 action send_goal``, and
its feedback cannot be lost to discovery (an action client made on the fly misses feedback
and results sent before DDS has matched its readers).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from action_msgs.msg import GoalStatus
from rclpy.action import CancelResponse, GoalResponse


@dataclass(frozen=True)
class LocalAction:
    """An action server's callbacks: ``on_goal(request)`` (None: accept every goal),
    ``execute(handle) -> result``, ``on_cancel(handle)`` (None: accept every cancel)."""

    action_type: type
    on_goal: Callable[[Any], GoalResponse] | None
    execute: Callable[[Any], Any]
    on_cancel: Callable[[Any], CancelResponse] | None = None

    def run(self, goal: Any, on_feedback: Callable[[Any], None],
            cancelled: Callable[[], bool], poll_s: float = 0.01) -> tuple[int, Any]:
        """Serve one goal to its end: (GoalStatus status, result). ``cancelled()`` asks for
        its cancellation (the cancel callback runs once, as for a ROS 2 client's request)."""
        if self.on_goal is not None and self.on_goal(goal) != GoalResponse.ACCEPT:
            raise GoalRejected("the action server rejected the goal")
        handle = LocalGoal(goal, on_feedback)
        done = threading.Event()
        outcome: list = []

        def execute() -> None:
            try:
                outcome.append(self.execute(handle))
            except BaseException as exc:  # noqa: BLE001 - reported as the goal's failure
                outcome.append(exc)
            finally:
                done.set()

        threading.Thread(target=execute, name="cosim-local-goal", daemon=True).start()
        while not done.wait(poll_s):
            if not handle.is_cancel_requested and cancelled():
                accept = self.on_cancel is None or (
                    self.on_cancel(handle) == CancelResponse.ACCEPT)
                handle.is_cancel_requested = accept
        if isinstance(outcome[0], BaseException):
            raise outcome[0]
        return handle.status, outcome[0]


class GoalRejected(RuntimeError):
    """The action server's goal callback refused the goal."""


class LocalGoal:
    """What an execute callback uses of rclpy's ServerGoalHandle."""

    def __init__(self, request: Any, on_feedback: Callable[[Any], None]):
        self.request = request
        self.is_cancel_requested = False
        self.status = GoalStatus.STATUS_EXECUTING
        self._on_feedback = on_feedback

    def publish_feedback(self, feedback: Any) -> None:
        """Hand one feedback message to the client."""
        self._on_feedback(feedback)

    def succeed(self) -> None:
        """The goal succeeded."""
        self.status = GoalStatus.STATUS_SUCCEEDED

    def abort(self) -> None:
        """The goal was aborted."""
        self.status = GoalStatus.STATUS_ABORTED

    def canceled(self) -> None:
        """The goal was cancelled."""
        self.status = GoalStatus.STATUS_CANCELED
