"""One starter per role of node (``plan.roles``), as mosaik's ``StarterCollection`` is a dict
of starters: a cosim node process (alone or packed with others), a foreign ROS 2 program
(behind either gate or none), a cosim node the user starts (``external: true``) and the
external inputs the orchestrator steps itself. A new kind of participant is one entry of
``STARTERS``.

A starter starts one process of the run's layout (``plan.packing.ProcessLayout``) and
returns it with the participant the tick loop talks to. The participant is built by ``join``
once the orchestrator's transport is open: over ros2 that must wait until every node is
forked (a process with rclpy loaded must not fork). Nothing here imports rclpy or zenoh at
module level, for the same reason.
"""

from __future__ import annotations

import logging
import random
import sys
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING

from orchestrator.lockstep.supervisor import (
    NodeProcess,
    Supervisor,
    fork_is_safe,
    node_argv,
    write_checked_plan,
)
from plan.options import RunOptions
from plan.packing import Process, ProcessLayout
from plan.roles import NodeRole
from plan.run_paths import RunPaths
from plan.scenario import Scenario
from runtime.arrivals import Arrivals, Replay
from runtime.recording import PartWriter

if TYPE_CHECKING:
    from orchestrator.lockstep.participants import Participant
    from runtime.transport.base import Transport

log = logging.getLogger("cosim")


@dataclass(frozen=True)
class Site:
    """What every starter needs: the scenario, where the run writes, its options, the
    supervisor of its processes, the run's process layout and what feeds the external
    node."""

    scenario: Scenario
    paths: RunPaths
    options: RunOptions
    supervisor: Supervisor
    layout: ProcessLayout
    external: Arrivals | Replay | None = None


@dataclass
class Started:
    """A started participant: its process (None when it has none of this run's: stepped in
    the orchestrator, or started by the user) and how to build its participants, node name
    -> participant, on the orchestrator's transport."""

    process: NodeProcess | None
    join: Callable[[Transport], dict[str, Participant]]


def start_cosim(site: Site, process: Process) -> Started:
    """Cosim nodes sharing one process (one name: a lone node): forked from this process
    when that is safe and no launch prefix wraps them, a fresh interpreter otherwise."""
    from runtime.cosim_node import run_lockstep, run_packed

    scenario, options, layout = site.scenario, site.options, site.layout
    names, label = list(process.names), process.label
    plan = scenario.nodes[names[0]]
    if options.spawn == "fork" and fork_is_safe() and not plan.launch_prefix:
        target = (partial(run_lockstep, scenario, names[0], site.paths.root, options, layout)
                  if len(names) == 1 else
                  partial(run_packed, scenario, names, site.paths.root, options, layout))
        proc = site.supervisor.fork(label, target)
    else:
        checked = write_checked_plan(scenario, site.paths.checked_plan)
        argv = node_argv(scenario.file, plan.spec.kind or "any", names, site.paths.root,
                         scenario.overrides, options, checked)
        proc = site.supervisor.spawn(label, argv, prefix=plan.launch_prefix)
    if len(names) > 1:
        site.supervisor.pack(proc, names)
    return Started(proc, partial(_cosim_nodes, site, names))


def start_foreign(site: Site, process: Process) -> Started:
    """A foreign ROS 2 program, started by its command in the scenario's folder; the
    orchestrator counts its outputs (``ForeignProxy``)."""
    from orchestrator.proxies.foreign_launch import foreign_argv, foreign_env, output_readers

    scenario = site.scenario
    plan = scenario.nodes[process.names[0]]
    readers = output_readers(scenario, site.layout, plan)
    proc = site.supervisor.spawn(plan.name, foreign_argv(plan, scenario.file.parent),
                                 prefix=plan.launch_prefix,
                                 env=foreign_env(plan, scenario.schedule, readers),
                                 cwd=scenario.file.parent.resolve())

    def join(transport: Transport) -> dict[str, Participant]:
        from orchestrator.proxies.foreign_proxy import ForeignProxy

        return {plan.name: ForeignProxy(plan, scenario.schedule, transport,
                                        PartWriter(site.paths.part(plan.name)))}

    return Started(proc, join)


def start_user_started(site: Site, process: Process) -> Started:
    """A cosim node the user starts (``external: true``): announced with its command."""
    scenario = site.scenario
    plan = scenario.nodes[process.names[0]]
    argv = node_argv(scenario.file, plan.spec.kind or "any", [plan.name], site.paths.root,
                     scenario.overrides, site.options)
    command = " ".join(["cosim-node", *argv[3:]])
    log.info("waiting for external node %s: %s", plan.name, command)
    print(f"cosim-orchestrate: waiting for external node {plan.name}; start it with:\n"
          f"  {command}", file=sys.stderr, flush=True)
    return Started(None, partial(_cosim_nodes, site, [plan.name]))


def start_in_orchestrator(site: Site, process: Process) -> Started:
    """The external node, stepped by the orchestrator on what arrives from outside (the
    run's arrivals or replay; fresh arrivals when it was given none)."""
    plan = site.scenario.nodes[process.names[0]]

    def join(transport: Transport) -> dict[str, Participant]:
        from orchestrator.proxies.external import ExternalSource

        scenario = site.scenario
        source = site.external if site.external is not None else Arrivals(plan.outputs)
        return {plan.name: ExternalSource(scenario, plan, transport,
                                          PartWriter(site.paths.part(plan.name)), source,
                                          site.layout)}

    return Started(None, join)


Starter = Callable[[Site, Process], Started]

STARTERS: dict[NodeRole, Starter] = {
    NodeRole.STEP: start_cosim,
    NodeRole.USER_STARTED: start_user_started,
    NodeRole.ORCHESTRATOR: start_in_orchestrator,
    NodeRole.PYTHON_GATE: start_foreign,
    NodeRole.RMW_GATE: start_foreign,
    NodeRole.UNGATED: start_foreign,
}
"""The starter of each role: a new kind of participant is one entry."""

START_LATE = {NodeRole.STEP: 1, NodeRole.ORCHESTRATOR: 2}
"""When each role starts (0 when not named): foreign programs first (they take longest to
start and join) with the nodes you start, then the cosim node processes, then the external
node."""


def start_all(site: Site) -> list[Started]:
    """Every process of the run's layout started by its role's starter, in the order of
    ``START_LATE`` and file order; the cosim node processes shuffled with the run option
    ``shuffle_start``."""
    processes = sorted(site.layout.processes, key=lambda p: START_LATE.get(p.role, 0))
    steps = site.layout.of_role(NodeRole.STEP)
    if site.options.shuffle_start is not None:
        random.Random(site.options.shuffle_start).shuffle(steps)
        others = iter(steps)
        processes = [next(others) if p.role is NodeRole.STEP else p for p in processes]
    started = [STARTERS[process.role](site, process) for process in processes]
    log.info("started %s", ", ".join(p.label for p in steps))
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
