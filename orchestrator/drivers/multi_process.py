"""The multi-process driver: the run's processes started by role (``orchestrator.starters``),
supervised (``orchestrator.lockstep.supervisor``) and driven tick by tick over the transport
by the lockstep master (``orchestrator.lockstep.master``). The nodes record their own
outputs; the run's control and ROS 2 simulation services are served here (ros2 runs).

Node processes are forked from this one before any transport library is loaded
(``Supervisor.fork``): nothing here imports rclpy or zenoh at module level, and what needs
them is imported once the nodes are started.
"""

from __future__ import annotations

import contextlib
import logging
import time

from orchestrator import run_domain
from orchestrator.drivers.face import Driver, Offer, RunContext, since_process_start
from orchestrator.lockstep.loop_result import LoopResult
from orchestrator.lockstep.supervisor import Supervisor
from orchestrator.starters import Site, join_all, start_all
from plan.errors import SimulationError
from plan.options import RunOptions, TransportSettings
from plan.packing import layout_of
from plan.roles import NodeRole
from plan.run_paths import RunPaths
from plan.scenario import Scenario
from runtime.arrivals import Arrivals
from runtime.transport.factory import create_transport

log = logging.getLogger("cosim")


class MultiProcessDriver(Driver):
    """Runs the scenario's nodes in processes of their own, in lockstep over the transport."""

    def start(self, ctx: RunContext) -> None:
        """Lay out and start the processes, open the orchestrator's transport (before them
        over zenoh, after them over ros2), join the participants, build the master, and
        serve the run's control (ros2 runs)."""
        scenario, options, paths = ctx.scenario, ctx.options, ctx.paths
        supervisor = Supervisor(paths.logs)
        layout = layout_of(scenario, options.pack, options.spread)  # the one place a run
        # decides its processes
        site = Site(scenario, paths, options, supervisor, layout, ctx.external)
        settings = TransportSettings.of(scenario, options)
        self.control_later = settings.kind == "ros2"
        if settings.kind == "ros2":  # every process a DDS participant, the orchestrator two
            widened = run_domain.widen_discovery(len(layout.processes) + 2)
            if widened:
                log.info("%s", widened)
        # zenoh nodes connect to the orchestrator's session, so it opens first (and the
        # nodes then start as fresh interpreters: a process with a session open must not
        # fork).
        opens_first = settings.kind == "zenoh"
        run = ctx.resources  # the run's resources, released in reverse order
        # the transport (and its DDS mirror) go last, whenever they were opened
        network = run.enter_context(contextlib.ExitStack())
        transport = _open_transport(settings) if opens_first else None
        if transport is not None:
            network.callback(transport.close)
            if settings.mirror_to_dds:  # its publishers are discovered while nodes start
                from orchestrator.live.dds_mirror import DdsMirror

                network.callback(DdsMirror(transport.session, transport.domain,
                                           list(settings.mirror_to_dds), scenario.topics,
                                           scenario.latched_topics).close)
        run.callback(supervisor.shutdown)
        starting = start_all(site)
        ctx.nodes_starting()
        if not any(p.started == "fork" for p in supervisor.processes()):
            # Fresh interpreters take seconds to start: load what the end of the run needs
            # meanwhile, so that a failed run exits promptly.
            import orchestrator.outputs.picture  # noqa: F401
        from orchestrator.lockstep.master import LockstepMaster

        if transport is None:
            transport = _open_transport(settings)
            network.callback(transport.close)
        participants = join_all(site, starting, transport)
        for name, participant in participants.items():
            if scenario.nodes[name].role.stood_in:
                run.callback(participant.recorder.close)
        self.transport = transport
        self.master = LockstepMaster(scenario, transport, supervisor, participants, options,
                                     layout, None, paths)
        run.callback(_keep_node_stats, ctx.outcome, self.master, supervisor)
        # the arrivals that ROS 2 servers put into (None: a replay, or no external node)
        live = next((p.arrivals for n, p in participants.items()
                     if scenario.nodes[n].role is NodeRole.ORCHESTRATOR
                     and isinstance(p.arrivals, Arrivals)), None)
        ctx.control, ctx.services = _ros_interfaces(scenario, options, paths, live)
        if ctx.services:
            run.callback(ctx.services.close)
        # Clients may connect while the nodes start (``serving``); they see the run once
        # it is ready.

    def wait_ready(self, ctx: RunContext) -> None:
        """Wait for every node (the start deadline counts from the run's start); refuse
        publishers that are not the scenario's."""
        try:
            self.master.wait_ready(ctx.started)
        except SimulationError as exc:  # a stray publisher can drive a node before tick 0
            _refuse_strangers(ctx.scenario, self.transport, cause=exc)
            raise
        _refuse_strangers(ctx.scenario, self.transport)
        ctx.outcome.start_s = time.monotonic() - ctx.started
        ctx.outcome.command_to_first_tick_s = since_process_start()
        log.info("all nodes ready after %.3f s", ctx.outcome.start_s)

    def loop(self, ctx: RunContext) -> LoopResult:
        """The master's tick loop, under the run's control, with the run's tick hooks."""
        self.master.on_tick = ctx.ticked()
        result = self.master.run(ctx.control)
        ctx.outcome.loop_s = time.monotonic() - self.master.loop_started
        return result

    def feed(self, ctx: RunContext, offer: Offer) -> None:
        """What the nodes record, read as it grows (``orchestrator.live.live_tail``), with
        /clock of every tick seen; nothing is added to the transport or the master's loop."""
        from orchestrator.live.live_tail import PartsTail

        scenario = ctx.scenario
        tail = PartsTail({name: ctx.paths.part(name) for name in scenario.nodes},
                         set(scenario.topics), scenario.tick_ns, offer)
        tail.start()
        ctx.resources.callback(tail.stop)


def _refuse_strangers(scenario: Scenario, transport, cause: Exception | None = None) -> None:
    """Fail the run before its first tick when a topic it reads (or /clock) has a
    publisher that is not the scenario's (runtime.intruders): its messages would be taken
    for the scenario's (``cause``: the start's own failure, which they explain). Topics of
    foreign programs are left out (their nodes are named by the programs)."""
    from runtime.intruders import REMEDY, graph_strangers
    from runtime.protocol import CLOCK_TOPIC

    topics = [CLOCK_TOPIC] + sorted({inp.graph_topic for plan in scenario.nodes.values()
                                     for inp in plan.inputs
                                     if not scenario.nodes[inp.producer].role.is_foreign})
    found = graph_strangers(transport, topics)
    if found:
        why = f" ({cause})" if cause is not None else ""
        raise SimulationError(f"{'; '.join(found)}. Nothing was lost: the run stopped before "
                              f"its first tick{why}. Remedy: {REMEDY}", node="orchestrator"
                              ) from cause


def _keep_node_stats(outcome, master, supervisor: Supervisor) -> None:
    """What the tick loop and the supervisor saw of each node, for the manifest."""
    outcome.ticks_done = max(master.tick, 0)
    outcome.node_stats = {name: (master.stats[name], supervisor.procs.get(name))
                          for name in master.scenario.nodes}
    outcome.supervisor = supervisor  # its memory figures are taken as it stops the nodes


def _open_transport(settings: TransportSettings):
    """The orchestrator's own participant; a failure to open it fails the run, named."""
    try:
        return create_transport(settings, "cosim_orchestrator")
    except Exception as exc:  # noqa: BLE001 - zenoh and rclpy raise their own types
        where = (f" (zenoh.listen {list(settings.zenoh_listen)}, zenoh.connect "
                 f"{list(settings.zenoh_connect)})" if settings.kind == "zenoh" else "")
        raise SimulationError(f"the orchestrator could not open its {settings.kind} "
                              f"transport{where}: {exc}", node="orchestrator") from exc


def _ros_interfaces(scenario: Scenario, options: RunOptions, paths: RunPaths,
                    live: Arrivals | None):
    """The run's control and its ROS 2 interfaces (orchestrator.ros_surface.sim_services):
    ros2 runs only, where ROS 2 tools can reach them; (None, None) otherwise."""
    if scenario.model.transport != "ros2":
        return None, None
    from orchestrator.ros_surface.sim_services import start_services
    from orchestrator.ros_surface.simcontrol import RunControl

    foreign = [n for n, p in scenario.nodes.items() if p.role.is_foreign]
    why = f"foreign program(s) {', '.join(foreign)} cannot be restarted" if foreign else None
    control = RunControl(scenario.tick_ns, paused=options.paused, cannot_reset=why)
    return control, start_services(scenario, control, live, paths)
