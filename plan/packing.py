"""Which nodes share an OS process: a deployment choice that never changes the result.

Every node is its own process unless the scenario gives nodes the same ``process:`` name,
or the run asks for a packing (``--pack``): ``node`` (each node alone), ``kind`` (the nodes
of one kind together, e.g. every sensors node), ``robot`` (every node of a robot together:
with one robot, all of the scenario's cosim nodes). Foreign programs, external nodes (that
you start yourself), the orchestrator's own nodes and nodes with a launch ``prefix`` are
never packed by ``--pack``.
"""

from __future__ import annotations

from plan.robots import robot_of
from plan.scenario import NodePlan, Scenario


def packable(plan: NodePlan) -> bool:
    """Whether the node runs as a cosim node process the orchestrator starts."""
    return not (plan.foreign or plan.in_orchestrator or plan.spec.external)


def process_groups(scenario: Scenario, pack: str | None) -> list[list[str]]:
    """The cosim node processes to start: lists of node names, in file order."""
    groups: dict[str, list[str]] = {}
    for name, plan in scenario.nodes.items():
        if not packable(plan):
            continue
        groups.setdefault(_group_of(name, plan, pack), []).append(name)
    return list(groups.values())


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


def process_of(scenario: Scenario, pack: str | None) -> dict[str, str]:
    """node name -> the process it runs in (a packed group's label; its own name when it
    runs alone or is not a cosim node process)."""
    out = {name: name for name in scenario.nodes}
    for group in process_groups(scenario, pack):
        for name in group:
            out[name] = process_label(group)
    return out


def subscribers(scenario: Scenario, pack: str | None, producer: str) -> dict[str, int]:
    """How many subscriptions each output topic of ``producer`` will match: one per process
    with a consumer of it (packed consumers share one subscription)."""
    where = process_of(scenario, pack)
    plan = scenario.nodes[producer]
    seen: dict[str, set[str]] = {topic: set() for topic in plan.outputs}
    for edge in scenario.schedule.edges:
        if edge.producer == producer:
            seen[edge.topic].add(where[edge.consumer])
    return {topic: len(processes) for topic, processes in seen.items()}
