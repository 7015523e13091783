"""The orchestrator's stand-in for a foreign program: it counts what the program publishes.

A foreign ROS 2 program cannot report on /cosim/status, so its proxy subscribes to the
program's outputs and reports for it: an activation is done once every output carries its
declared number of messages; the digest covers exactly those bytes. A program that
publishes more than it declared is an error the moment it happens; one that publishes too
few is caught by the tick deadline, naming what is missing.
"""

from __future__ import annotations

import time

from nodes.runtime.cdr.canonical import canonical_cdr
from nodes.runtime.exchange import output_digest
from nodes.runtime.protocol import DONE, Done, Status
from nodes.runtime.recording import PartWriter
from nodes.runtime.transport.base import Received, Transport
from orchestrator.participants import Participant
from plan.errors import SimulationError

SETTLE_S = 0.5


class ForeignProxy(Participant):
    """Counts one foreign program's outputs and turns them into status reports."""

    foreign = True

    def __init__(self, plan, period: int, transport: Transport, recorder: PartWriter | None):
        self.name = plan.name
        self.period = period
        self.per = {graph: plan.params.count(own) for own, graph in plan.output_names.items()}
        self.classes = dict(plan.outputs)
        self.subs = {t: transport.subscription(t, cls, 1000) for t, cls in self.classes.items()}
        self.received: dict[str, list[bytes]] = {t: [] for t in self.classes}
        self.recorder = recorder
        self.activations = 0
        self._matched_since: float | None = None

    @property
    def topics(self) -> frozenset[str]:
        """The program's output topics."""
        return frozenset(self.subs)

    def ready(self) -> bool:
        """Whether the program's publishers have been matched for ``SETTLE_S`` (it has
        started and joined). Our readers seeing its writers does not prove its writers
        see our readers yet, and a volatile writer drops what it publishes before that:
        the settle time covers the other half of discovery, which cosim cannot observe
        in a program it does not run."""
        if not all(sub.matched() >= 1 for sub in self.subs.values()):
            self._matched_since = None
            return False
        now = time.monotonic()
        if self._matched_since is None:
            self._matched_since = now
        return now - self._matched_since >= SETTLE_S

    def not_ready_text(self) -> str:
        """Outputs the program has not yet advertised, for the start-deadline message."""
        missing = [t for t, sub in self.subs.items() if sub.matched() < 1]
        return ("is a foreign program whose outputs are not advertised yet: "
                + ", ".join(f"{t} (0/1 publishers)" for t in missing) + " (see its log)")

    def take(self, rec: Received, current_tick: int) -> list[Status]:
        """File one output message; return DONE reports for activations now complete."""
        messages = self.received[rec.topic]
        messages.append(canonical_cdr(rec.data, self.classes[rec.topic]))
        activation = (len(messages) - 1) // self.per[rec.topic]
        if activation * self.period > current_tick:
            raise SimulationError(
                f"foreign node {self.name} published more than {self.per[rec.topic]} "
                f"message(s) on {rec.topic} at tick {current_tick}: message {len(messages)} "
                f"would belong to tick {activation * self.period}. Declare the count in "
                f"params.per_activation, or make the program publish once per input.",
                node=self.name, tick=current_tick)
        done = []
        while self._complete(self.activations):
            done.append(self._finish(self.activations))
            self.activations += 1
        return done

    def _complete(self, activation: int) -> bool:
        return all(len(self.received[t]) >= (activation + 1) * n for t, n in self.per.items())

    def _finish(self, activation: int) -> Status:
        tick = activation * self.period
        items = []
        for topic in sorted(self.per):
            n = self.per[topic]
            items += [(topic, data) for data in
                      self.received[topic][activation * n:(activation + 1) * n]]
        if self.recorder:
            self.recorder.write(tick, items)
        done = Done(self.name, tick, output_digest(tick, items).hex())
        return Status(self.name, DONE, tick, done=[done])

    def owed_text(self, tick: int) -> str:
        """What the program still owes for ``tick``, e.g. '0 of 1 messages on /cmd_vel'."""
        activation = tick // self.period
        parts = [f"{max(0, len(self.received[t]) - activation * n)} of {n} message(s) on {t}"
                 for t, n in sorted(self.per.items())]
        return "it published " + ", ".join(parts) + " (foreign program)"
