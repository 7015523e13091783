"""The checked scenario and its resolved nodes: what every later layer reads.

``descriptions.load.load_scenario`` reads a file into a ``Scenario``; this module only defines
what it returns.
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from plan.model import NodeSpec, ScenarioModel
from plan.robots import RobotsLayout
from plan.roles import NodeRole
from plan.schedule import Schedule, first_activation
from plan.timeutil import Ns

EXTERNAL_NAME = "external"  # the node that the scenario's external: section becomes


@dataclass(frozen=True)


class InputPlan:
    """A resolved input: the node's own topic name, the graph topic, its producer and type."""

    topic: str
    graph_topic: str
    producer: str
    mode: str
    msg_type: type


@dataclass(frozen=True)


class NodePlan:
    """A resolved node: its class, checked parameters, period and remapped topics."""

    name: str
    spec: NodeSpec
    class_ref: str
    params: BaseModel
    period_ticks: int
    outputs: dict[str, type]  # graph topic -> message class (latched ones included)
    output_names: dict[str, str]  # node's own topic -> graph topic
    inputs: list[InputPlan]
    role: NodeRole  # what part it plays in a run (plan.roles), decided once at load
    latched: frozenset[str] = frozenset()  # own names of the outputs published once, latched
    windows: dict[str, tuple[int, int | None]] = field(default_factory=dict)  # own output
    # name -> [start, end) ticks it is published in (a robot that enters or leaves the run)
    relatch: set[int] = field(default_factory=set)  # ticks its latched outputs are due again
    output_periods: dict[str, int] = field(default_factory=dict)  # own output name -> its
    # period in ticks, a multiple of the node's (published at those activations only)
    unconsumed: frozenset[str] = frozenset()  # own names of the outputs no node of the run
    # takes: a message its step marks quiet there is left out (nodes.contract.quiet_message)

    def windowed(self, tick: int, first: bool) -> tuple[dict[str, str], frozenset[str], bool]:
        """(own -> graph names, latched own names, first) of the outputs due at ``tick``
        (``runtime.activation``): a windowed output only inside its window, a windowed
        latched one at the node's first activation inside it; a latched one without a
        window at the first activation and again at each ``relatch`` tick (a robot entered:
        /tf_static with its fixed frames too); an output with a period of its own
        (``output_periods``) only at ticks that are multiples of it."""
        p = self.period_ticks
        names, due_latched = {}, set()
        for own, graph in self.output_names.items():
            if tick % self.output_periods.get(own, 1):
                continue
            window = self.windows.get(own)
            if window is not None and (tick < window[0] or (window[1] is not None
                                                            and tick >= window[1])):
                continue
            names[own] = graph
            if own not in self.latched:
                continue
            if window is not None and window[0] > 0:
                if tick == first_activation(p, window[0]):
                    due_latched.add(own)
            elif first or tick in self.relatch:
                due_latched.add(own)
        names = {own: g for own, g in names.items() if own not in self.latched
                 or own in due_latched}
        return names, frozenset(), False
    @property
    def latched_topics(self) -> frozenset[str]:
        """Graph names of the outputs published once, at the first activation, latched."""
        return frozenset(self.output_names[own] for own in self.latched)

    @property
    def declared_outputs(self) -> dict[str, type]:
        """The node's own output topic names -> message classes (before remap)."""
        return {own: self.outputs[graph] for own, graph in self.output_names.items()}

    @property
    def launch_prefix(self) -> list[str]:
        """The command that wraps the node's process (scenario key ``prefix``), split."""
        return shlex.split(self.spec.prefix) if self.spec.prefix else []

    @property
    def gate(self) -> str | None:
        """The gate that serves this foreign program ('python' or 'rmw', ``plan.gates``), or
        None: not foreign, or the RMW gate it needs is not built (its role's)."""
        return self.role.gate

    @property
    def gated_outputs(self) -> list[str]:
        """A gated program's output topics (graph names) in the order its gate counts them
        in each acknowledgement."""
        return sorted(self.output_names.values())


@dataclass


class Scenario:
    """A checked scenario: the model, its file, tick, nodes in file order and the schedule."""

    file: Path
    model: ScenarioModel
    tick_ns: Ns  # exact: a Fraction where not whole ns (plan.timeutil)
    nodes: dict[str, NodePlan]
    schedule: Schedule
    world: Path | None
    sha256: str
    overrides: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)  # ScenarioNotice texts
    robots: RobotsLayout | None = None  # the robots: section laid out (plan/robots.py)

    @property
    def name(self) -> str:
        """The scenario's name."""
        return self.model.name

    @property
    def topics(self) -> dict[str, type]:
        """Every published graph topic and its message class."""
        out: dict[str, type] = {}
        for plan in self.nodes.values():
            out.update(plan.outputs)
        return out

    @property
    def latched_topics(self) -> frozenset[str]:
        """Graph topics published once per run, latched (transient-local), e.g. /tf_static."""
        return frozenset(t for plan in self.nodes.values() for t in plan.latched_topics)

    @property
    def trailing_nodes(self) -> frozenset[str]:
        """The nodes that may trail the others by up to one activation: leaves of the graph
        (nothing consumes their outputs), not foreign, and not a node that runs a controller
        manager (its metrics answer the manager's services at every tick). Their metrics
        never decide an early stop, on any driver."""
        return frozenset(n for n in self.schedule.leaves() if not self.nodes[n].role.is_foreign
                         and getattr(self.nodes[n].params, "controller_manager", None) is None)

    def open_robot(self, robot: str, tick: int) -> None:
        """A robot a client brings in enters at ``tick``: its nodes' and topics' windows
        start there (``plan.schedule``), and the world node's latched outputs are due again
        then. Every driver and node process applies the same opening at the same tick
        boundary (the orchestrator's handshake), before any node reaches it."""
        self._change_window(robot, lambda w: (tick, w[1]))
        for plan in self.nodes.values():
            if plan.windows and plan.latched:
                plan.relatch.add(tick)

    def close_robot(self, robot: str, tick: int) -> None:
        """A robot a client takes out leaves at ``tick``: its windows end there."""
        self._change_window(robot, lambda w: (w[0], tick))

    def _change_window(self, robot: str, change) -> None:
        sched, prefix = self.schedule, f"/{robot}/"
        for node, window in sched.windows.items():
            if node.partition("@")[2] == robot:
                sched.windows[node] = change(window)
        for topic, window in sched.topic_windows.items():
            if topic.startswith(prefix):
                sched.topic_windows[topic] = change(window)
        for plan in self.nodes.values():
            for own, window in plan.windows.items():
                if plan.output_names[own].startswith(prefix):
                    plan.windows[own] = change(window)

    def producer_of(self, topic: str) -> str:
        """The node that publishes a graph topic."""
        for plan in self.nodes.values():
            if topic in plan.outputs:
                return plan.name
        raise KeyError(topic)
