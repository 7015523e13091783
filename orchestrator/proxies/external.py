"""What enters a run from outside, at tick boundaries (the scenario's ``external:`` node).

``Arrivals`` collects messages from any thread (an action server, a rosbridge client, a
twin's connection) as they come. ``ExternalSource`` is the master's participant for the
``external`` node: when /clock reaches one of its ticks, nothing of that tick has started
anywhere, so it hands the messages that arrived since its last activation to the node's
step as that tick's inputs, publishes the outputs, records them and reports the
activation done, like a node process would. What it takes is recorded as it arrived
(``arrivals_record``); a replay feeds recorded arrivals instead.
"""

from __future__ import annotations

from nodes.contract import Tick
from orchestrator.lockstep.participants import Participant
from orchestrator.proxies.arrivals_record import arrival_items
from plan.packing import ProcessLayout
from plan.scenario import NodePlan, Scenario
from runtime.activation import Activation
from runtime.arrivals import Arrivals, Replay
from runtime.build import make_node
from runtime.exchange import output_digest
from runtime.protocol import DONE, Done, Status
from runtime.recording import PartWriter
from runtime.transport.base import Transport


class ExternalSource(Participant):
    """Steps the ``external`` node in the orchestrator, one activation per due tick."""

    def __init__(self, scenario: Scenario, plan: NodePlan, transport: Transport,
                 recorder: PartWriter | None, arrivals: Arrivals | Replay,
                 layout: ProcessLayout):
        self.name = plan.name
        self.plan = plan
        self.scenario = scenario
        self.schedule = scenario.schedule
        self.node = make_node(scenario, plan.name)
        self.activation = Activation(plan, self.node)
        self.arrivals = arrivals
        self.recorder = recorder
        depth = self.schedule.output_depths(self.name, plan.outputs)
        self.expected = layout.subscribers(self.name)
        self.publishers = {t: transport.publisher(t, cls, depth[t])
                           for t, cls in plan.outputs.items()}
        self.pending: list[Status] = []
        self.sent = {t: 0 for t in self.publishers}  # per topic, for the reset handshake

    def ready(self) -> bool:
        """Whether every consumer's subscription has matched (a message is never lost)."""
        return all(pub.matched() >= self.expected[t] for t, pub in self.publishers.items())

    def not_ready_text(self) -> str:
        """Consumers not matched yet."""
        missing = [f"{t} ({pub.matched()}/{self.expected[t]} subscriptions)"
                   for t, pub in self.publishers.items() if pub.matched() < self.expected[t]]
        return "(in the orchestrator) still waiting for discovery of " + ", ".join(missing)

    def owed_text(self, tick: int) -> str:
        """It never owes anything past its tick's start."""
        return "it runs in the orchestrator and publishes when /clock reaches its tick"

    def start_tick(self, tick: int) -> None:
        """/clock reached ``tick``: when due, take what arrived and publish."""
        if not self.schedule.is_due(self.name, tick):
            return
        inputs = (self.arrivals(tick) if callable(self.arrivals)
                  else self.arrivals.take(tick))
        if self.recorder and inputs:
            self.recorder.write(tick, arrival_items(inputs))
        when = Tick(tick, self.schedule.time_ns(tick))
        items = self.activation(when, inputs)
        for topic, data in items:
            self.publishers[topic].publish(data)
            self.sent[topic] += 1
        if self.recorder:
            self.recorder.write(tick, items)
        done = Done(self.name, tick, output_digest(tick, items).hex(), 0,
                    {k: float(v) for k, v in self.node.metrics().items()})
        self.pending.append(Status(self.name, DONE, tick, done=[done]))

    def drain(self) -> list[Status]:
        """The activations published since the last call."""
        done, self.pending = self.pending, []
        return done

    def reset(self) -> None:
        """Back to tick 0 (the run's reset): the node starts over, the record too."""
        self.activation.restart(self.scenario.model.seed)
        self.pending.clear()
        if isinstance(self.arrivals, Arrivals):
            self.arrivals.take(0)  # what came before the reset is no part of the new run
        if self.recorder:
            self.recorder.truncate()
