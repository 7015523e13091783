"""The goal protocol every controller with an action shares: the orchestrator (the manager's
face) serves the action, and its goals and cancels enter the controller at a tick boundary
on ``~/cosim/goal``, named ``cosim-goal-<n>`` (a goal) or ``cosim-cancel-<n>`` (a cancel);
the newest goal's number (``n``), state and result code reach the face as the controller's
metrics. A newer goal preempts the one executing; a cancel ends it, holding; a deactivation
aborts it as upstream does (INVALID_GOAL, "Current goal cancelled during deactivate
transition.")."""

from __future__ import annotations

GOAL_ID, CANCEL_ID = "cosim-goal-", "cosim-cancel-"  # + a number: the face's name of it
# the state of the newest action goal (the metric ``goal_state``)
IDLE, ACTIVE, SUCCEEDED, ABORTED, CANCELED = 0, 1, 2, 3, 4
SUCCESSFUL, INVALID_GOAL = 0, -1  # control_msgs' result codes the protocol itself gives
DEACTIVATED = "Current goal cancelled during deactivate transition."


def number(name: str) -> int:
    """``n`` of ``cosim-goal-<n>`` / ``cosim-cancel-<n>`` (0 when it carries none)."""
    digits = name.rpartition("-")[2]
    return int(digits) if digits.isdigit() else 0


class GoalProtocol:
    """The newest action goal of one controller: its number (the face's ``n``), state,
    result code, and whether a deactivation ended it."""

    def __init__(self):
        self.goal_id = 0
        self.state = IDLE
        self.error_code = SUCCESSFUL
        self.deactivated = False

    @staticmethod
    def kind(name: str) -> str | None:
        """'goal', 'cancel' or None (not the face's: the external node's stand-in)."""
        if name.startswith(GOAL_ID):
            return "goal"
        if name.startswith(CANCEL_ID):
            return "cancel"
        return None

    @property
    def executing(self) -> bool:
        """Whether a goal is executing."""
        return self.state == ACTIVE

    def begin(self, name: str) -> None:
        """Goal ``name`` enters: the one executing is preempted (cancelled)."""
        self.goal_id = number(name)
        self.state, self.error_code, self.deactivated = ACTIVE, SUCCESSFUL, False

    def end(self, state: int, code: int = SUCCESSFUL) -> bool:
        """The executing goal ends as ``state`` with ``code``; whether one was executing."""
        if self.state != ACTIVE:
            return False
        self.state, self.error_code = state, code
        return True

    def deactivate(self) -> bool:
        """The controller is deactivated: the executing goal is aborted (INVALID_GOAL)."""
        self.deactivated = self.end(ABORTED, INVALID_GOAL)
        return self.deactivated

    def metrics(self) -> dict[str, float]:
        """``goal_seq`` (the newest goal's number), ``goal_state``, ``error_code`` and
        ``deactivated`` (1: a deactivation aborted it)."""
        return {"goal_seq": float(self.goal_id), "goal_state": float(self.state),
                "error_code": float(self.error_code), "deactivated": float(self.deactivated)}
