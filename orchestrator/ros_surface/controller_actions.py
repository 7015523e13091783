"""What the controller manager's face needs to serve each controller action: how a client's
goal enters the run (named, on the controller's ``~/cosim/goal``), how a cancel does, and the
result the controller's metrics make of it. One face per action type; a controller offers
its actions (``ControllerInterface.actions``) and the face of their type serves them."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from control_msgs.action import FollowJointTrajectory, ParallelGripperCommand
from sensor_msgs.msg import JointState

from nodes.ros2_control.goals import ABORTED, CANCELED, DEACTIVATED, GOAL_ID, SUCCEEDED

RESULT_TEXT = {0: "", -1: "invalid goal", -2: "invalid joints", -3: "old header timestamp",
               -4: "path tolerance violated", -5: "goal tolerance violated"}


@dataclass(frozen=True)
class Ending:
    """How a goal ends: the handle's call (succeed, abort, canceled), its result, a text."""

    how: str
    result: Any
    text: str = ""


class _NamedGoalFace:
    """What every action face shares: a goal enters the run named in the frame_id of the
    header of its ``field`` (the controller tells a new goal from the one the external node
    holds by it), a cancel is an empty goal with that name, and a goal is told from a cancel
    by the name's prefix."""

    action: Any
    field: str

    @classmethod
    def entering(cls, request, name: str):
        """The goal as it enters the run, named in its ``field``'s header."""
        goal = cls.action.Goal()
        for slot in goal.get_fields_and_field_types():
            setattr(goal, slot, getattr(request, slot))
        getattr(goal, cls.field).header.frame_id = name
        return goal

    @classmethod
    def cancel(cls, name: str):
        """A cancel as it enters the run."""
        cancel = cls.action.Goal()
        getattr(cancel, cls.field).header.frame_id = name
        return cancel

    @classmethod
    def is_goal(cls, msg) -> bool:
        """Whether ``msg`` (what an arrival replaced) was a goal."""
        return getattr(msg, cls.field).header.frame_id.startswith(GOAL_ID)


class FollowJointTrajectoryFace(_NamedGoalFace):
    """control_msgs/action/FollowJointTrajectory of a joint trajectory controller."""

    action = FollowJointTrajectory
    field = "trajectory"
    feedback_topic = "~/controller_state"  # what the executing goal's feedback is made of

    @staticmethod
    def refuse(request) -> str | None:
        """Nothing is refused before the controller sees the goal."""
        return None




    @staticmethod
    def failed(how: str, text: str, code: int | None = None) -> Ending:
        """A goal that ends outside the controller (never entered, replaced, the run ended):
        ``code`` -1 (INVALID_GOAL) when aborted, 0 when cancelled, unless given."""
        if code is None:
            code = -1 if how == "abort" else 0
        return Ending(how, FollowJointTrajectory.Result(error_code=code, error_string=text),
                      text)

    @staticmethod
    def ended(state: float, metrics: dict[str, float], ctrl, cancel_requested: bool
              ) -> Ending | None:
        """The ending the controller's metrics (its own names) say, or None (still going)."""
        if state == SUCCEEDED:
            return Ending("succeed", FollowJointTrajectory.Result(error_code=0,
                                                                  error_string=""))
        if state == ABORTED:
            code = int(metrics.get("error_code", 0.0))
            joint = int(metrics.get("error_joint", -1.0))
            text = DEACTIVATED if metrics.get("deactivated") else RESULT_TEXT.get(code, "")
            if joint >= 0:
                text += f" (joint {ctrl.joints[joint]})"
            return Ending("abort", FollowJointTrajectory.Result(error_code=code,
                                                                error_string=text), text)
        if state == CANCELED:
            how = "canceled" if cancel_requested else "abort"
            text = "cancelled: holding position" if how == "canceled" else "preempted"
            return Ending(how, FollowJointTrajectory.Result(error_code=0, error_string=text),
                          text)
        return None

    @staticmethod
    def feedback(state) -> FollowJointTrajectory.Feedback:
        """The feedback of a JointTrajectoryControllerState."""
        return FollowJointTrajectory.Feedback(header=state.header,
                                              joint_names=list(state.joint_names),
                                              desired=state.reference, actual=state.feedback,
                                              error=state.error)


class ParallelGripperFace(_NamedGoalFace):
    """control_msgs/action/ParallelGripperCommand of a parallel gripper action controller."""

    action = ParallelGripperCommand
    field = "command"
    feedback_topic = None

    @staticmethod
    def refuse(request) -> str | None:
        """As upstream's goal callback: one position, or the goal is rejected."""
        n = len(request.command.position)
        return None if n == 1 else f"{n} positions, expects 1"




    @staticmethod
    def failed(how: str, text: str, code: int | None = None) -> Ending:
        """A goal that ends outside the controller (the result carries no code)."""
        return Ending(how, ParallelGripperCommand.Result(), text)

    @staticmethod
    def ended(state: float, metrics: dict[str, float], ctrl, cancel_requested: bool
              ) -> Ending | None:
        """Succeeded or aborted with the joint's state (stalled, reached), cancelled."""
        if state in (SUCCEEDED, ABORTED):
            result = ParallelGripperCommand.Result(
                state=JointState(name=[ctrl.params.joint],
                                 position=[metrics.get("position", 0.0)], effort=[0.0]),
                stalled=bool(metrics.get("stalled")),
                reached_goal=bool(metrics.get("reached_goal")))
            text = "stalled" if result.stalled else ""
            if metrics.get("deactivated"):
                text = DEACTIVATED
            return Ending("succeed" if state == SUCCEEDED else "abort", result, text)
        if state == CANCELED:
            how = "canceled" if cancel_requested else "abort"
            return Ending(how, ParallelGripperCommand.Result(),
                          "cancelled: holding position" if how == "canceled" else "preempted")
        return None


FACES = {face.action: face for face in (FollowJointTrajectoryFace, ParallelGripperFace)}
"""action type -> its face."""
