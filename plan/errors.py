"""The two ways a run can fail, after mosaik: before anything starts, or during the run."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


class ScenarioError(Exception):
    """The scenario is invalid; raised before any process starts (CLI exit code 2).

    The message is one paragraph naming the file, the key path and what would be accepted;
    one found with others in the same pass (``every``) lists them all, one per line.
    """

    def __init__(self, file: str, key: str, problem: str, accepted: str = ""):
        self.file = str(file)
        self.key = key
        self.problem = problem
        self.accepted = accepted
        self.errors: tuple[ScenarioError, ...] = (self,)
        text = f"{self.file}: {key}: {problem}" if key else f"{self.file}: {problem}"
        if accepted:
            text += f" Accepted: {accepted}"
        super().__init__(text)

    @classmethod
    def every(cls, errors: list[ScenarioError]) -> ScenarioError:
        """One error for all of ``errors`` (each a single problem): the error itself when
        there is one; else the first's file, key and fix, its message numbering every
        problem on a line of its own with its key and fix, and ``errors`` holding them."""
        if len(errors) == 1:
            return errors[0]
        first = errors[0]
        combined = cls(first.file, first.key, first.problem, first.accepted)
        combined.errors = tuple(errors)
        lines = [f"{first.file}: {len(errors)} problems:"]
        for n, error in enumerate(errors, 1):
            text = str(error).removeprefix(f"{first.file}: ")
            lines.append(f"  {n}. {text}")
        Exception.__init__(combined, "\n".join(lines))
        return combined


class Problems:
    """The problems found in one pass over a scenario: each check whose own input is right
    runs, and what each finds is kept (``collecting``), so that a scenario with several
    independent mistakes is refused once, naming them all (``raise_any``)."""

    def __init__(self) -> None:
        self.errors: list[ScenarioError] = []

    @contextmanager
    def collecting(self) -> Iterator[None]:
        """Keep the ScenarioError the block raises (each of its problems once) and go on."""
        try:
            yield
        except ScenarioError as exc:
            self.add(exc)

    def add(self, error: ScenarioError) -> None:
        """Keep each problem of ``error`` not kept yet (two checks may find one thing)."""
        self.errors += [e for e in error.errors if str(e) not in map(str, self.errors)]

    def raise_any(self) -> None:
        """Raise every problem kept so far as one ScenarioError; nothing when none."""
        if self.errors:
            raise ScenarioError.every(self.errors)


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
