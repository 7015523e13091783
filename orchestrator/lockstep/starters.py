"""One starter per kind of participant, as mosaik's starters: a cosim node process (alone
or packed with others), a foreign ROS 2 program, a cosim node the user starts
(``external: true``) and the external inputs the orchestrator steps itself.

A starter starts its process and returns it with the participant the tick loop talks to.
The participant is built by ``join`` once the orchestrator's transport is open: over ros2
that must wait until every node is forked (a process with rclpy loaded must not fork).
Nothing here imports rclpy or zenoh at module level, for the same reason.
"""

from __future__ import annotations

import logging
import random
import sys
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING

from orchestrator.lockstep.supervisor import NodeProcess, Supervisor, fork_is_safe, node_argv
from plan.options import RunOptions
from plan.packing import process_label
from plan.run_paths import RunPaths
from plan.scenario import NodePlan, Scenario
from runtime.arrivals import Arrivals, Replay
from runtime.recording import PartWriter

if TYPE_CHECKING:
    from orchestrator.lockstep.participants import Participant
    from runtime.transport.base import Transport

log = logging.getLogger("cosim")


@dataclass(frozen=True)
class Site:
    """What every starter needs: the scenario, where the run writes, its options, the
    supervisor of its processes and what feeds the external node."""

    scenario: Scenario
    paths: RunPaths
    options: RunOptions
    supervisor: Supervisor
    external: Arrivals | Replay | None = None


@dataclass
class Started:
    """A started participant: its process (None when it has none of this run's: stepped in
    the orchestrator, or started by the user) and how to build its participants, node name
    -> participant, on the orchestrator's transport."""

    process: NodeProcess | None
    join: Callable[[Transport], dict[str, Participant]]


def start_cosim(site: Site, names: list[str]) -> Started:
    """Cosim nodes sharing one process (one name: a lone node): forked from this process
    when that is safe and no launch prefix wraps them, a fresh interpreter otherwise."""
    from runtime.cosim_node import run_lockstep, run_packed

    scenario, options = site.scenario, site.options
    plan = scenario.nodes[names[0]]
    label = process_label(names)
    if options.spawn == "fork" and fork_is_safe() and not plan.launch_prefix:
        target = (partial(run_lockstep, scenario, names[0], site.paths.root, options)
                  if len(names) == 1 else
                  partial(run_packed, scenario, names, site.paths.root, options))
        proc = site.supervisor.fork(label, target)
    else:
        argv = node_argv(scenario.file, plan.spec.kind or "any", names, site.paths.root,
                         scenario.overrides, options)
        proc = site.supervisor.spawn(label, argv, prefix=plan.launch_prefix)
    if len(names) > 1:
        site.supervisor.pack(proc, names)
    return Started(proc, partial(_cosim_nodes, site, names))


def start_foreign(site: Site, plan: NodePlan) -> Started:
    """A foreign ROS 2 program, started by its command in the scenario's folder; the
    orchestrator counts its outputs (``ForeignProxy``)."""
    from orchestrator.proxies.foreign_launch import foreign_argv, foreign_env, output_readers

    scenario = site.scenario
    readers = output_readers(scenario, site.options.pack, plan)
    proc = site.supervisor.spawn(plan.name, foreign_argv(plan, scenario.file.parent),
                                 prefix=plan.launch_prefix,
                                 env=foreign_env(plan, scenario.schedule, readers),
                                 cwd=scenario.file.parent.resolve())

    def join(transport: Transport) -> dict[str, Participant]:
        from orchestrator.proxies.foreign_proxy import ForeignProxy

        return {plan.name: ForeignProxy(plan, scenario.schedule, transport,
                                        PartWriter(site.paths.part(plan.name)))}

    return Started(proc, join)


def start_user_started(site: Site, plan: NodePlan) -> Started:
    """A cosim node the user starts (``external: true``): announced with its command."""
    scenario = site.scenario
    argv = node_argv(scenario.file, plan.spec.kind or "any", [plan.name], site.paths.root,
                     scenario.overrides, site.options)
    command = " ".join(["cosim-node", *argv[3:]])
    log.info("waiting for external node %s: %s", plan.name, command)
    print(f"cosim-orchestrate: waiting for external node {plan.name}; start it with:\n"
          f"  {command}", file=sys.stderr, flush=True)
    return Started(None, partial(_cosim_nodes, site, [plan.name]))


def start_in_orchestrator(site: Site, plan: NodePlan) -> Started:
    """The external node, stepped by the orchestrator on what arrives from outside (the
    run's arrivals or replay; fresh arrivals when it was given none)."""
    def join(transport: Transport) -> dict[str, Participant]:
        from orchestrator.proxies.external import ExternalSource

        scenario = site.scenario
        source = site.external if site.external is not None else Arrivals(plan.outputs)
        return {plan.name: ExternalSource(scenario, plan, transport,
                                          PartWriter(site.paths.part(plan.name)), source,
                                          site.options.pack)}

    return Started(None, join)


def start_all(site: Site) -> list[Started]:
    """Every participant of the run started: foreign programs first (they take longest to
    start and join) and user-started nodes announced, in file order; then the cosim node
    processes (``plan.packing``), shuffled with the run option ``shuffle_start``; then the
    external node."""
    from plan.packing import process_groups, process_label

    scenario = site.scenario
    started = []
    for plan in scenario.nodes.values():
        if plan.foreign:
            started.append(start_foreign(site, plan))
        elif plan.spec.external:
            started.append(start_user_started(site, plan))
    groups = process_groups(scenario, site.options.pack)
    if site.options.shuffle_start is not None:
        random.Random(site.options.shuffle_start).shuffle(groups)
    started += [start_cosim(site, names) for names in groups]
    log.info("started %s", ", ".join(process_label(g) for g in groups))
    started += [start_in_orchestrator(site, plan) for plan in scenario.nodes.values()
                if plan.in_orchestrator]
    return started


def join_all(site: Site, started: list[Started], transport: Transport
             ) -> dict[str, Participant]:
    """Every started participant on the orchestrator's transport, in the scenario's order."""
    joined: dict[str, Participant] = {}
    for one in started:
        joined.update(one.join(transport))
    return {name: joined[name] for name in site.scenario.nodes}


def _cosim_nodes(site: Site, names: list[str], transport: Transport) -> dict[str, Participant]:
    from orchestrator.lockstep.participants import CosimNode

    return {name: CosimNode(site.scenario.nodes[name], site.scenario.schedule)
            for name in names}
