"""Which nodes share an OS process: a deployment choice that never changes the result.

Every node is its own process unless the scenario gives nodes the same ``process:`` name,
or the run asks for a packing (``--pack``): ``node`` (each node alone), ``kind`` (the nodes
of one kind together, e.g. every sensors node; with ``--spread N`` each kind's nodes over at
most N processes, in runs of consecutive nodes, so a swarm's lidars and controllers work in
parallel on N cores without a process per node), ``robot`` (every node of a robot together:
with one robot, all of the scenario's cosim nodes). Foreign programs, external nodes (that
you start yourself), the orchestrator's own nodes and nodes with a launch ``prefix`` are
never packed by ``--pack`` (only the role ``STEP`` packs, ``plan.roles``).

A run decides this once, into a ``ProcessLayout`` (``layout_of``), and carries that value to
the starters, the master, the node runtimes, the external node and the foreign programs'
readers; nothing else groups nodes again.
"""

from __future__ import annotations

from dataclasses import dataclass

from plan.robots import robot_of
from plan.roles import NodeRole
from plan.scenario import NodePlan, Scenario


@dataclass(frozen=True)
class Process:
    """What one starter starts: a process holding cosim nodes (several when packed), a
    foreign program, a node you start, or the external node's participant inside the
    orchestrator. ``label`` names it (its log file, its process name)."""

    label: str
    names: tuple[str, ...]
    role: NodeRole


@dataclass(frozen=True)
class ProcessLayout:
    """The run's process layout, decided once from the scenario and the packing
    (``layout_of``) and carried to everyone who needs it: the starters, the master, the
    node runtimes, the external node and the foreign programs' readers."""

    pack: str | None
    processes: tuple[Process, ...]  # in the order of their first node in the file
    process_of: dict[str, str]  # node name -> the label of the process it runs in
    readers: dict[str, dict[str, int]]  # producer -> output topic -> subscriptions it matches

    def subscribers(self, producer: str) -> dict[str, int]:
        """How many subscriptions each output topic of ``producer`` will match: one per
        process with a consumer of it (packed consumers share one subscription)."""
        return self.readers[producer]

    def of_role(self, *roles: NodeRole) -> list[Process]:
        """The processes of these roles, in layout order."""
        return [p for p in self.processes if p.role in roles]

    @property
    def node_processes(self) -> list[Process]:
        """The processes running cosim step nodes (the orchestrator's and yours): each has
        one /cosim/command subscription, and one /clock subscription when a node in it
        follows /clock."""
        return [p for p in self.processes if p.role.runs_step_runtime]


def layout_of(scenario: Scenario, pack: str | None, spread: int | None = None
              ) -> ProcessLayout:
    """The process layout of a run of ``scenario`` with packing ``pack`` (and, packed by
    kind, ``spread`` processes at most a kind): computed once per run (by the orchestrator;
    by a node process from its command line)."""
    keyed: dict[str, list[str]] = {}
    roles: dict[str, NodeRole] = {}
    for name, plan in scenario.nodes.items():
        key = _group_of(name, plan, pack) if plan.role.packable else f"node:{name}"
        keyed.setdefault(key, []).append(name)
        roles[key] = plan.role
    if spread is not None:
        keyed, roles = _spread(keyed, roles, spread)
    processes = tuple(Process(process_label(names) if roles[key].packable else names[0],
                              tuple(names), roles[key]) for key, names in keyed.items())
    where = {name: p.label for p in processes for name in p.names}
    readers = {}
    for producer, plan in scenario.nodes.items():
        seen: dict[str, set[str]] = {topic: set() for topic in plan.outputs}
        for edge in scenario.schedule.edges:
            if edge.producer == producer:
                seen[edge.topic].add(where[edge.consumer])
        readers[producer] = {topic: len(labels) for topic, labels in seen.items()}
    return ProcessLayout(pack, processes, where, readers)


def _spread(keyed: dict[str, list[str]], roles: dict[str, NodeRole], spread: int
            ) -> tuple[dict[str, list[str]], dict[str, NodeRole]]:
    """Each packed group split into at most ``spread`` runs of consecutive nodes (of n
    nodes, node i goes to run i * spread // n), in the order of their first node."""
    out: dict[str, list[str]] = {}
    out_roles: dict[str, NodeRole] = {}
    for key, names in keyed.items():
        parts = spread if roles[key].packable else 1
        for i, name in enumerate(names):
            part = f"{key}/{i * parts // len(names)}"
            out.setdefault(part, []).append(name)
            out_roles[part] = roles[key]
    return out, out_roles


def _group_of(name: str, plan: NodePlan, pack: str | None) -> str:
    if pack is None:
        return f"process:{plan.spec.process}" if plan.spec.process else f"node:{name}"
    if pack == "node" or plan.spec.prefix:
        return f"node:{name}"
    if pack == "kind":
        return f"kind:{plan.spec.kind or plan.spec.module}"
    robot = robot_of(name)  # a swarm: each robot's nodes together, the world's apart
    return f"robot:{robot}" if robot else "robot"


LABEL_MAX = 80  # characters: the label names the process's log file (NAME_MAX is 255)


def process_label(names: list[str]) -> str:
    """The name of a process holding ``names``: 'a+b+c', or for a long group (a swarm's
    controllers packed together) its first node and how many more, 'control@robot_0+15_more'."""
    label = "+".join(names)
    return label if len(label) <= LABEL_MAX else f"{names[0]}+{len(names) - 1}_more"
