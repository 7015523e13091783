"""Action goals from the live endpoints run an action server's own callbacks
(orchestrator/ros_surface/local_goals.py): goal, execute and cancel, as rclpy runs them."""

from __future__ import annotations

import threading

import pytest
from action_msgs.msg import GoalStatus
from rclpy.action import CancelResponse, GoalResponse
from simulation_interfaces.action import SimulateSteps

from orchestrator.ros_surface.local_goals import GoalRejected, LocalAction


def counting(steps_done: list, release: threading.Event):
    """An execute callback like SimulateSteps': feedback per step until cancelled."""
    def execute(handle):
        for i in range(1, handle.request.steps + 1):
            if handle.is_cancel_requested:
                handle.canceled()
                return SimulateSteps.Result()
            handle.publish_feedback(SimulateSteps.Feedback(completed_steps=i))
            steps_done.append(i)
            release.wait(0.01)
        handle.succeed()
        return SimulateSteps.Result()
    return execute


def test_a_goal_runs_to_its_result_with_its_feedback():
    feedback: list = []
    action = LocalAction(SimulateSteps, None, counting([], threading.Event()))
    status, result = action.run(SimulateSteps.Goal(steps=4), feedback.append, lambda: False)
    assert status == GoalStatus.STATUS_SUCCEEDED and isinstance(result, SimulateSteps.Result)
    assert [f.completed_steps for f in feedback] == [1, 2, 3, 4]


def test_a_cancel_runs_the_cancel_callback_once_and_ends_the_goal():
    cancels, done = [], []
    action = LocalAction(SimulateSteps, None, counting(done, threading.Event()),
                         lambda handle: cancels.append(handle) or CancelResponse.ACCEPT)
    status, _ = action.run(SimulateSteps.Goal(steps=100_000), lambda _f: None,
                           lambda: len(done) >= 3)
    assert status == GoalStatus.STATUS_CANCELED and len(cancels) == 1
    assert 3 <= len(done) < 100_000


def test_a_refused_cancel_lets_the_goal_finish():
    action = LocalAction(SimulateSteps, None, counting([], threading.Event()),
                         lambda _h: CancelResponse.REJECT)
    status, _ = action.run(SimulateSteps.Goal(steps=20), lambda _f: None, lambda: True)
    assert status == GoalStatus.STATUS_SUCCEEDED


def test_a_rejected_goal_never_executes():
    ran = []
    action = LocalAction(SimulateSteps, lambda _req: GoalResponse.REJECT, ran.append)
    with pytest.raises(GoalRejected):
        action.run(SimulateSteps.Goal(steps=1), lambda _f: None, lambda: False)
    assert ran == []


def test_an_execute_that_raises_fails_the_goal():
    def broken(_handle):
        raise RuntimeError("broken server")

    with pytest.raises(RuntimeError, match="broken server"):
        LocalAction(SimulateSteps, None, broken).run(SimulateSteps.Goal(), lambda _f: None,
                                                     lambda: False)
