"""What the lockstep master drives: one participant per node of the scenario.

A participant is either a cosim node process, which reports for itself on
``/cosim/status``, or a foreign program, whose stand-in in the orchestrator
(``orchestrator.proxies.foreign_proxy``) reads its outputs and reports for it. The master treats
both alike: it asks whether each is ready, files what arrives for it, and asks what it
still owes when a deadline passes.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from plan.scenario import NodePlan
from plan.schedule import Schedule
from runtime.protocol import READY, STATUS_TOPIC, Status
from runtime.transport.base import Received


class Participant(ABC):
    """One node of the run as the master sees it."""

    name: str
    follows_clock: bool = False  # it reads the run's /clock itself: no clock may run ahead

    @property
    def topics(self) -> frozenset[str]:
        """Run topics (besides /cosim/status) whose messages are filed with ``take``."""
        return frozenset()

    def see(self, status: Status) -> None:  # noqa: B027 - most participants ignore it
        """A status report of this participant arrived (cosim nodes only)."""

    def take(self, rec: Received, tick: int) -> list[Status]:
        """File a message of one of ``topics`` at the master's current ``tick``; return the
        status reports it completes."""
        return []

    def start_tick(self, tick: int) -> None:  # noqa: B027 - most participants ignore it
        """The master published /clock for ``tick``."""

    def drain(self) -> list[Status]:
        """Status reports completed without a message (the master asks in every wait)."""
        return []

    def reset(self) -> None:  # noqa: B027 - only participants without a process need it
        """The run's reset, for a participant without a process of its own."""

    @abstractmethod
    def ready(self) -> bool:
        """Whether the participant has started and its discovery is complete."""

    @abstractmethod
    def not_ready_text(self) -> str:
        """What it still waits for, for the start-deadline message."""

    @abstractmethod
    def owed_text(self, tick: int) -> str:
        """What it still needs or owes for ``tick``, for the tick-deadline message."""


class CosimNode(Participant):
    """A cosim node process: it reports waiting, ready, done and error itself."""

    def __init__(self, plan: NodePlan, schedule: Schedule):
        self.name = plan.name
        self.plan = plan
        self.schedule = schedule
        self.last: Status | None = None
        self._ready = False

    def see(self, status: Status) -> None:
        """Remember the latest report; 'ready' once seen stays true until a reset."""
        self.last = status
        if status.state == READY:
            self._ready = True

    def ready(self) -> bool:
        """Whether it reported ready (every publisher and subscription matched)."""
        return self._ready

    def not_ready_text(self) -> str:
        """The topics its last report names as unmatched."""
        if self.last and self.last.detail:
            return f"still waiting for discovery of {self.last.detail}"
        return "never reported on " + STATUS_TOPIC

    def owed_text(self, tick: int) -> str:
        """The input samples it needs for ``tick``."""
        needs = [f"{self.plan.inputs[index].graph_topic} of tick {wanted}"
                 for index, wanted in self.schedule.inputs_at(self.name, tick)]
        return f"it needs {', '.join(needs)}" if needs else "it needs no input"
