"""The two ways a run can fail, after mosaik: before anything starts, or during the run."""

from __future__ import annotations

from pathlib import Path


class ScenarioError(Exception):
    """The scenario is invalid; raised before any process starts (CLI exit code 2).

    The message is one paragraph naming the file, the key path and what would be accepted.
    """

    def __init__(self, file: str, key: str, problem: str, accepted: str = ""):
        self.file = str(file)
        self.key = key
        self.problem = problem
        self.accepted = accepted
        text = f"{self.file}: {key}: {problem}" if key else f"{self.file}: {problem}"
        if accepted:
            text += f" Accepted: {accepted}"
        super().__init__(text)


class ScenarioNotice(str):
    """A scenario warning: its text (worded as a ScenarioError, printed and kept in the
    manifest as is) that also keeps the file, key, problem and fix, so that a strict run
    can refuse it as the error it would be (``as_error``)."""

    def __new__(cls, file: str, key: str, problem: str, accepted: str = ""):
        """The text of ``ScenarioError(file, key, problem, accepted)``, with its parts."""
        notice = super().__new__(cls, str(ScenarioError(file, key, problem, accepted)))
        notice.file, notice.key, notice.problem, notice.accepted = (
            str(file), key, problem, accepted)
        return notice

    def __getnewargs__(self):
        return self.file, self.key, self.problem, self.accepted

    def as_error(self, why: str) -> ScenarioError:
        """The ScenarioError this warning is when ``why`` (e.g. a strict run) refuses it."""
        return ScenarioError(self.file, self.key, f"{self.problem} ({why})", self.accepted)


class SimulationError(Exception):
    """A run failed after it started (CLI exit code 3): names the node and what went wrong."""

    def __init__(self, message: str, node: str | None = None, tick: int | None = None):
        self.node = node
        self.tick = tick
        super().__init__(message)


class ScenarioWarning(UserWarning):
    """Something in a scenario that runs but deserves a word (e.g. an output nobody reads)."""


class WorldError(ValueError):
    """A world file that cannot be loaded: the file, the prim (USD) and the reason (raised by
    the world loader, ``descriptions.worldfile``; here so that plan/ can report it)."""

    def __init__(self, file: Path | str, reason: str, prim: str | None = None):
        self.file, self.prim, self.reason = str(file), prim, reason
        where = f"{self.file}, prim {prim}" if prim else self.file
        super().__init__(f"world {where}: {reason}")
