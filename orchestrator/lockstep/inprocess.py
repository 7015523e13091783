"""The in-process reference: the same step classes and schedule, one process, no transport."""

from __future__ import annotations

import time
from collections.abc import Callable

from nodes.contract import StepNode, Tick
from nodes.live_params import ParamsInput
from orchestrator.lockstep.loop_result import LoopResult, goal_reached
from orchestrator.lockstep.pace import Pace
from plan.errors import SimulationError
from plan.roles import NodeRole
from plan.scenario import Scenario
from runtime.activation import Activation
from runtime.build import make_node
from runtime.collector import hold_for_loop, release_after_loop
from runtime.exchange import InputHistory, RunDigest, SharedDecoder, output_digest
from runtime.notes import Note

Observer = Callable[[int, str, list[tuple[str, bytes]]], None]
"""Called after each activation with (tick, node, [(topic, bytes)])."""


def run_in_process(scenario: Scenario, observer: Observer | None = None,
                   on_tick: Callable[[int], None] | None = None,
                   external: Callable[[int], dict] | None = None,
                   pace: Pace | None = None) -> LoopResult:
    """Run every node in this process in schedule order; return the digest, metrics and
    the nodes' notes. ``external(tick)`` gives what enters from outside at a tick of the
    external node. With a ``pace``, each tick waits for its time on the wall clock."""
    sched = scenario.schedule
    nodes = {name: make_node(scenario, name) for name in sched.order}
    notes: list[Note] = []
    activations = {name: Activation(scenario.nodes[name], nodes[name], notes.append,
                                    ParamsInput.of(scenario.nodes[name]))
                   for name in sched.order}
    shared = SharedDecoder()  # one message per sample for the nodes that only read theirs
    readers = {name for name, node in nodes.items() if node.shares_inputs}
    histories = {(plan.name, inp.topic): InputHistory(inp.graph_topic, inp.msg_type,
                                                      shared if plan.name in readers else None)
                 for plan in scenario.nodes.values() for inp in plan.inputs}
    for plan in scenario.nodes.values():  # a dormant node keeps no samples
        for edge, inp in zip(sched.inputs_of[plan.name], plan.inputs, strict=True):
            histories[(plan.name, inp.topic)].keep_for(sched, edge)
    consumers: dict[str, list[InputHistory]] = {}
    for plan in scenario.nodes.values():
        for inp in plan.inputs:
            consumers.setdefault(inp.graph_topic, []).append(histories[(plan.name, inp.topic)])
    digest = RunDigest()
    cost: dict[str, list[int]] = {}
    stop = scenario.model.success.stop_on_goal and scenario.model.has_goal
    before = hold_for_loop()  # what exists now lives all run; a tick's messages till taken
    try:
        for k in range(sched.n_ticks):
            tick = Tick(k, sched.time_ns(k))
            if pace is not None:
                pace.hold(tick.time_ns)
            for name in sched.due(k):
                plan = scenario.nodes[name]
                inputs = {}
                for index, wanted in sched.inputs_at(name, k):
                    own = plan.inputs[index].topic
                    inputs[own] = histories[(name, own)].take(wanted)
                if plan.role is NodeRole.ORCHESTRATOR and external is not None:
                    inputs = external(k)
                started = time.perf_counter_ns()  # for the manifest only, never for outputs
                try:
                    items = activations[name](tick, inputs)
                except Exception as exc:
                    raise SimulationError(f"node {name} failed at tick {k}: "
                                          f"{type(exc).__name__}: {exc}",
                                          node=name, tick=k) from exc
                _account(cost.setdefault(name, [0, 0, 0]), time.perf_counter_ns() - started)
                digest.add(k, name, output_digest(k, items))
                for topic, data in items:
                    for history in consumers.get(topic, ()):
                        history.push_bytes(k, data)
                if observer:
                    observer(k, name, items)
            if on_tick:
                on_tick(k)
            if stop and goal_reached({n: nodes[n].metrics() for n in nodes},
                                     scenario.trailing_nodes):
                return LoopResult(digest.hexdigest(), k + 1, _metrics(nodes), True, cost, notes)
        return LoopResult(digest.hexdigest(), sched.n_ticks, _metrics(nodes), False, cost, notes)
    finally:
        release_after_loop(before)


def _account(entry: list[int], step_ns: int) -> None:
    entry[0] += 1
    entry[1] += step_ns
    entry[2] = max(entry[2], step_ns)


def _metrics(nodes: dict[str, StepNode]) -> dict[str, dict[str, float]]:
    return {name: node.metrics() for name, node in nodes.items()}
