"""cosim-node: run one node of a scenario (spawned by the orchestrator, or on its own)."""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from runtime.entry import guarded

if TYPE_CHECKING:
    from plan.packing import ProcessLayout
    from plan.scenario import Scenario

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130
EPILOG = """\
exit codes:
  0    stopped as asked (by its orchestrator, or Ctrl-C for --realtime)
  1    the node failed: its step raised, or its runtime could not go on (the log says why)
  2    bad input: the scenario, the node or an option is invalid; nothing was started
  70   internal error: an exception cosim did not expect (its fault); the traceback is
       printed and kept in a file the last line names
  130  interrupted (SIGINT) in lockstep before its orchestrator asked it to stop
"""


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    p = argparse.ArgumentParser(
        prog="cosim-node", epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run one node of a cosim scenario. With --lockstep (the default) it joins "
                    "an orchestrator's run and acts only when /clock says so.")
    p.add_argument("kind", help="the node's kind (physics, sensors, control, ...) or 'any'")
    p.add_argument("--scenario", required=True, type=Path, help="scenario YAML file")
    p.add_argument("--node", action="append",
                   help="which node of the scenario (default: the only one of KIND); given "
                        "several times, those nodes share this process (--lockstep only)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--lockstep", action="store_true",
                      help="join a running orchestrator's lockstep run (the default); a node "
                           "marked 'external: true' in the scenario is started this way by you")
    mode.add_argument("--realtime", action="store_true",
                      help="free-run on wall time: physics publishes /clock and takes /cmd_vel "
                           "from anyone; sensors and control follow /clock")
    p.add_argument("--rtf", type=float, default=1.0,
                   help="real-time factor for --realtime (default 1.0; 2.0 runs twice as fast)")
    p.add_argument("--live", nargs="?", const="127.0.0.1:8765", metavar="ADDR:PORT",
                   help="with --realtime: a Foxglove WebSocket server streaming what the node "
                        "publishes and receives (default 127.0.0.1:8765)")
    p.add_argument("--rosbridge", nargs="?", const="127.0.0.1:9090", metavar="ADDR:PORT",
                   help="with --realtime: a rosbridge v2 server (roslibpy, roslibjs): watch "
                        "the node's topics, publish its inputs, pause and step a node that "
                        "publishes /clock (default 127.0.0.1:9090)")
    p.add_argument("--run-dir", type=Path, help="where to record what this node publishes")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key, as the orchestrator does (repeatable)")
    p.add_argument("--run-options", metavar="JSON", help=argparse.SUPPRESS)  # orchestrator's
    p.add_argument("--plan", type=Path, help=argparse.SUPPRESS)  # the orchestrator's checked
    # scenario (orchestrator.lockstep.supervisor.write_checked_plan), instead of checking again
    return p


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line options."""
    return build_parser().parse_args(argv)


def pick_node(scenario: Scenario, kind: str, name: str | None) -> str:
    """The node to run: by name (of kind ``kind`` unless that is 'any'), or the only node of
    ``kind``."""
    if name:
        if name not in scenario.nodes:
            raise ValueError(f"{scenario.file}: no node named {name!r} "
                             f"(nodes: {', '.join(scenario.nodes)})")
        actual = scenario.nodes[name].spec.kind
        if kind != "any" and actual != kind:
            what = f"of kind {actual!r}" if actual else "not of a built-in kind (module:)"
            fix = actual or "any"
            raise ValueError(f"{scenario.file}: node {name!r} is {what}, not {kind!r}; run "
                             f"cosim-node {fix} --scenario {scenario.file} --node {name}")
        return name
    matches = [n for n, p in scenario.nodes.items()
               if p.spec.kind == kind or (kind == "any" and not p.role.is_foreign)]
    if len(matches) != 1:
        raise ValueError(f"{scenario.file}: {len(matches)} nodes of kind {kind!r}; "
                         f"name one with --node ({', '.join(scenario.nodes)})")
    return matches[0]


@guarded("cosim-node")
def main(argv: list[str] | None = None) -> int:
    """Entry point of cosim-node."""
    if argv is None:  # a command (not a call from a program): its own ROS 2 libraries
        from runtime.ros_libraries import ensure_own_libraries

        ensure_own_libraries()
    from runtime.parent import die_with_parent, started_by_orchestrator

    if started_by_orchestrator():  # a node the user starts is the user's: it outlives a shell
        die_with_parent(watchdog=True)
    args = parse_args(argv)
    import nodes  # noqa: F401 - provides the node kinds to the plan (plan.kinds)
    from descriptions.load import load_scenario
    from plan.errors import ScenarioError
    from plan.options import RunOptions
    from plan.overrides import parse_overrides

    try:
        scenario = (checked_plan(args.plan, args.scenario) if args.plan else
                    load_scenario(args.scenario, parse_overrides(args.set)))
        # several --node: a process of packed nodes, named by its first node's kind
        names = [pick_node(scenario, args.kind if i == 0 else "any", n)
                 for i, n in enumerate(args.node or [None])]
        if len(names) > 1 and args.realtime:
            raise ValueError("--realtime runs one node; give --node once")
        options = RunOptions.from_node_json(args.run_options)
        if (args.live or args.rosbridge) and not args.realtime:
            raise ValueError("--live and --rosbridge serve a --realtime node; a lockstep run "
                             "gets them from cosim-orchestrate")
        live = RunOptions(live=args.live, rosbridge=args.rosbridge)
    except (ScenarioError, ValueError) as exc:
        print(f"cosim-node: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    from plan.packing import layout_of, process_label
    from runtime.parent import name_this_process

    name_this_process(process_label(names))
    if args.realtime:
        return run_realtime(scenario, names[0], args.rtf, options, live)
    # a process started from a command line has only the file and the options: it lays the
    # run out as the orchestrator did (the same function of the same two values)
    layout = layout_of(scenario, options.pack, options.spread)
    if len(names) > 1:
        return run_packed(scenario, names, args.run_dir, options, layout)
    if not started_by_orchestrator():
        print(f"cosim-node {names[0]}: {lockstep_waits_for(scenario, names[0])}",
              file=sys.stderr, flush=True)
    return run_lockstep(scenario, names[0], args.run_dir, options, layout)


def checked_plan(path: Path, scenario_file: Path) -> Scenario:
    """The scenario its orchestrator checked and wrote for this run (``--plan``), which must
    be of the file given with ``--scenario``: the whole plan is checked once, before any
    process starts, and a process it starts need not check it again (nor compile the swarm
    world: its models come with the plan)."""
    import pickle

    from descriptions.swarm_world import take_over
    from plan.load import make_importable
    from plan.scenario import Scenario

    make_importable(scenario_file.parent, Path.cwd())  # its module: nodes, as loading does
    try:
        scenario, models = pickle.loads(path.read_bytes())
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError,
            TypeError, ValueError) as exc:  # the last two: not a (plan, models) pair
        raise ValueError(f"--plan {path}: cannot read the orchestrator's checked plan "
                         f"({exc}); leave --plan out to load {scenario_file}") from None
    if not isinstance(scenario, Scenario) or (Path(scenario.file).resolve()
                                              != scenario_file.resolve()):
        raise ValueError(f"--plan {path} is not the checked plan of {scenario_file}; leave "
                         "--plan out to load the scenario")
    take_over(models)  # the swarm world as the orchestrator compiled it, not compiled again
    return scenario


def lockstep_waits_for(scenario: Scenario, name: str) -> str:
    """What a lockstep node started by hand waits for, where, and what the user probably
    meant instead."""
    import os

    if scenario.model.transport == "zenoh":
        where = "over zenoh (the scenario's zenoh: section)"
    else:
        where = f"on ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')} (ros2)"
    from plan.roles import NodeRole

    if scenario.nodes[name].role == NodeRole.USER_STARTED:
        then = (f"start the run with cosim-orchestrate {scenario.file}: it waits for this "
                "node (external: true) and prints the command that starts it on the run's "
                "domain")
    else:
        then = (f"to run the scenario, use cosim-orchestrate {scenario.file} (it starts this "
                "node itself); to run this node alone on wall time, add --realtime")
    return (f"lockstep: waiting for an orchestrator's /clock and grants {where}; nothing "
            f"happens until one runs. {then[0].upper()}{then[1:]}.")


def run_realtime(scenario: Scenario, name: str, rtf: float, options=None, live=None) -> int:
    """Run node ``name`` free-running on wall time until Ctrl-C; ``live`` (RunOptions with
    ``live``/``rosbridge``) adds the live endpoints."""
    import signal

    from plan.listen import address_problems, exposure_warnings
    from plan.options import TransportSettings
    from runtime.build import make_node
    from runtime.realtime import RealtimeRuntime
    from runtime.transport.factory import create_transport

    if live is not None and (live.live or live.rosbridge):
        addresses = (live.live_address, live.rosbridge_address)
        problems = address_problems(*addresses)
        if problems:
            print(f"cosim-node {name}: {'; '.join(problems)}", file=sys.stderr)
            return EXIT_BAD_INPUT
        for warning in exposure_warnings(*addresses):
            print(f"cosim-node {name}: warning: {warning}", file=sys.stderr, flush=True)
    transport = create_transport(TransportSettings.of(scenario, options), f"cosim_{name}")
    endpoints = None
    try:
        runtime = RealtimeRuntime(scenario, name, _built(make_node, scenario, name, options),
                                  transport, rtf)
        signal.signal(signal.SIGINT, runtime.request_stop)
        signal.signal(signal.SIGTERM, runtime.request_stop)
        endpoints = _start_endpoints(scenario, name, runtime, live)
        clock = "publishing /clock" if runtime.publish_clock else "following /clock"
        print(f"cosim-node {name}: running on wall time at rtf {rtf:g}, {clock}; Ctrl-C stops",
              file=sys.stderr, flush=True)
        try:
            runtime.run()
        except Exception as exc:  # noqa: BLE001 - the node's step raised: the node failed
            import traceback

            traceback.print_exc()
            print(f"cosim-node {name}: the node failed: {type(exc).__name__}: {exc}",
                  file=sys.stderr)
            return EXIT_FAILED
        return EXIT_OK
    except KeyboardInterrupt:
        return EXIT_OK
    except SetUpFailed:
        return EXIT_FAILED
    except ValueError as exc:
        print(f"cosim-node {name}: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except RuntimeError as exc:  # an endpoint could not listen
        print(f"cosim-node {name}: {exc}", file=sys.stderr)
        return EXIT_FAILED
    finally:
        if endpoints is not None:
            runtime.observe = None
            endpoints.close()
        transport.close()


def _start_endpoints(scenario: Scenario, name: str, runtime, live):
    """The realtime node's live endpoints, when asked for: its outputs, inputs and /clock
    to watch, its inputs to drive, pause and step when it paces itself."""
    if live is None or not (live.live or live.rosbridge):
        return None
    from rosgraph_msgs.msg import Clock

    from runtime.live.endpoints import Catalog
    from runtime.live.session import LiveEndpoints
    from runtime.protocol import CLOCK_TOPIC

    plan = scenario.nodes[name]
    topics = {CLOCK_TOPIC: Clock, **{i.graph_topic: i.msg_type for i in plan.inputs},
              **plan.outputs}
    catalog = Catalog(dict(sorted(topics.items())), inbox=runtime.inbox,
                      services=runtime.control,
                      no_inbox_text=f"node {name} has no inputs to drive",
                      inbox_what=f"an input of node {name}",
                      latched=frozenset(plan.latched_topics))
    endpoints = LiveEndpoints(catalog, live.live_address, live.rosbridge_address,
                              f"cosim-node {name}")
    for line in endpoints.start():
        print(f"cosim-node {name}: {line}", file=sys.stderr, flush=True)
    runtime.observe = endpoints.offer
    return endpoints


def run_lockstep(scenario: Scenario, name: str, run_dir: Path | None, options,
                 layout: ProcessLayout) -> int:
    """Run node ``name`` under an orchestrator until told to stop, in the run's ``layout``."""
    from plan.options import RunOptions
    from plan.run_paths import RunPaths
    from runtime.build import make_node
    from runtime.collector import hold_for_loop
    from runtime.lockstep import LockstepRuntime, NodeFailure, install_stop_handlers
    from runtime.notes import NoteWriter
    from runtime.recording import PartWriter

    options = options or RunOptions()
    paths = RunPaths(run_dir) if run_dir else None

    # Publishers and subscriptions first: DDS discovery then runs in the transport's own
    # threads while the node builds its model (MuJoCo compile, renderer set-up).
    transport = _open_transport(scenario, options, f"cosim_{name}")
    recorder = PartWriter(paths.part(name)) if paths else None
    notes = NoteWriter(paths.notes(name)) if paths else None
    runtime = LockstepRuntime(scenario, name, None, transport, recorder, notes, layout=layout)
    install_stop_handlers(runtime)
    try:
        runtime.node = _built(make_node, scenario, name, options)
        hold_for_loop()  # runtime.collector: for the rest of the process
        _run_maybe_profiled(runtime, paths, name, options.profile)
        return EXIT_OK
    except KeyboardInterrupt:  # a step cut short by the orchestrator's stop is a clean end
        return EXIT_OK if runtime.stop_requested else EXIT_INTERRUPTED
    except SetUpFailed:
        return EXIT_FAILED
    except NodeFailure as exc:
        return _failed(runtime, exc)
    finally:
        _write_timing(runtime, paths, name)  # also when stopped in the middle of a step
        if recorder:
            recorder.close()
        if notes:
            notes.close()
        transport.close()


def run_packed(scenario: Scenario, names: list[str], run_dir: Path | None, options,
               layout: ProcessLayout) -> int:
    """Run several nodes in this process, on one transport session with one wait."""
    from plan.options import RunOptions
    from plan.run_paths import RunPaths
    from runtime.build import make_node
    from runtime.collector import hold_for_loop
    from runtime.lockstep import LockstepRuntime, NodeFailure
    from runtime.notes import NoteWriter
    from runtime.packed import PackedRuntimes, install_packed_stop_handlers
    from runtime.recording import PartWriter
    from runtime.shared_transport import SharedTransport

    options = options or RunOptions()
    paths = RunPaths(run_dir) if run_dir else None
    base = _open_transport(scenario, options, "cosim_" + "_".join(names))
    shared = SharedTransport(base)
    recorders = {n: PartWriter(paths.part(n)) if paths else None for n in names}
    notes = {n: NoteWriter(paths.notes(n)) if paths else None for n in names}
    runtimes = [LockstepRuntime(scenario, n, None, shared.view(), recorders[n], notes[n],
                                layout=layout) for n in names]
    packed = PackedRuntimes(runtimes, shared)
    install_packed_stop_handlers(packed)
    failed = None
    try:
        for rt in runtimes:
            failed = rt
            rt.node = _built(make_node, scenario, rt.name, options)
        failed = None
        hold_for_loop()  # runtime.collector: for the rest of the process
        packed.run()
        return EXIT_OK
    except KeyboardInterrupt:
        return EXIT_OK if packed.stop_requested else EXIT_INTERRUPTED
    except SetUpFailed:
        return EXIT_FAILED
    except NodeFailure as exc:
        return _failed(next((rt for rt in runtimes if rt.in_step), failed) or runtimes[0], exc)
    finally:
        for rt in runtimes:
            _write_timing(rt, paths, rt.name)
        for writer in [*recorders.values(), *notes.values()]:
            if writer:
                writer.close()
        shared.close()


def _open_transport(scenario: Scenario, options, participant: str):
    """The node process's transport, its threads started with SIGALRM blocked (they inherit
    this thread's mask), so the alarm that reports before a slow step always lands on the
    thread that runs the step."""
    from plan.options import TransportSettings
    from runtime.transport.factory import create_transport

    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGALRM})
    try:
        return create_transport(TransportSettings.of(scenario, options), participant)
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGALRM})


class SetUpFailed(Exception):
    """The node's own set-up (its class's reset/setup) raised: the node failed, exit 1."""


def _built(make_node, scenario: Scenario, name: str, options):
    """``make_node(...)``; what the node's code raises while setting up is the node's failure
    (exit 1, the traceback in its log), never an internal error of cosim."""
    try:
        return make_node(scenario, name, options)
    except Exception as exc:  # noqa: BLE001 - the node class's code: the node failed
        import traceback

        traceback.print_exc()
        print(f"cosim-node {name}: the node failed to set up: {type(exc).__name__}: {exc}",
              file=sys.stderr, flush=True)
        raise SetUpFailed(str(exc)) from exc


def _failed(runtime, exc) -> int:
    """A node's runtime could not go on: report the error unless the step already did (it
    reports its own exception with the tick), print why, return the exit code."""
    if exc.__cause__ is None:
        runtime.report_error(-1, exc)
    print(f"cosim-node {runtime.name}: {exc}", file=sys.stderr)
    if exc.__cause__ is not None:
        import traceback

        traceback.print_exception(exc.__cause__, file=sys.stderr)
    return EXIT_FAILED


def _write_timing(runtime, paths, name: str) -> None:
    """Leave the run loop's time split next to the node's log, for the manifest."""
    if paths is not None and runtime.timing.started is not None:
        try:
            runtime.timing.write(paths.timing(name))
        except OSError:
            pass  # the run directory is gone: nothing to add to


def _run_maybe_profiled(runtime, paths, name: str, mode: str | None) -> None:
    """Run; with the run option ``profile`` and a run directory, write a cProfile of the
    node there ('cpu' counts the main thread's CPU time instead of wall time: on a loaded
    machine wall time charges a call for the other processes that ran meanwhile)."""
    if not (mode and paths):
        runtime.run()
        return
    import cProfile
    import time

    profiler = cProfile.Profile(time.thread_time) if mode == "cpu" else cProfile.Profile()
    try:
        profiler.runcall(runtime.run)
    finally:
        profiler.dump_stats(paths.profile(name))


if __name__ == "__main__":
    sys.exit(main())
