"""cosim-orchestrate: check a scenario, run it in lockstep, record it, report it."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from plan.options import PACKINGS, PROFILE_MODES, SPAWN_MODES, TRANSPORTS
from runtime.entry import guarded, interruptible

EXIT_SUCCESS, EXIT_GOAL_NOT_MET, EXIT_BAD_INPUT, EXIT_NODE_FAILED = 0, 1, 2, 3
EXIT_INTERRUPTED = 130
EXIT_DIGEST_MISMATCH = 4
EXIT_WRITE_FAILED = 5
EXIT_INTERNAL_ERROR = 70  # runtime.entry's: what nobody expected, cosim's own fault

EPILOG = """\
exit codes:
  0    success: the scenario's success criteria were met
  1    the run finished but the goal was not met (or too many collisions)
  2    bad input: the scenario or an option is invalid; nothing was started or written
  3    a node failed: crashed, reported an error, or missed its deadline; or a twin
       (--twin) never reached its robot
  4    the run finished but its digest is not the one --expect-digest (or --against) names
       (with --ignore-rendered: its digest without the rendered topics, in manifest.json),
       or a rendered frame is below the --rendered-psnr floor
  5    could not write the run's outputs (a full disk): the run stopped at a tick, named
       the file and its file system; the bag keeps every tick before it, manifest.json
       says where it stopped (or how to finish the run directory)
  70   internal error: an exception cosim did not expect (its fault, not the scenario's);
       the traceback is printed and kept in a file the last line names
  130  interrupted (SIGINT or SIGTERM); every node was stopped, outputs were kept

outputs go to runs/<scenario>-<timestamp>/ (see --out): manifest.json with the run
digest, bag/ (every topic, MCAP), report.png and per-node logs under logs/ (parts/, what
each node recorded itself, stays only when the bag could not be built from it).
"""


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    p = argparse.ArgumentParser(
        prog="cosim-orchestrate", epilog=EPILOG, formatter_class=argparse.RawTextHelpFormatter,
        description="Run a cosim scenario: start every node as its own process, advance them "
                    "in lockstep on /clock over ROS 2,\nand write a deterministic run digest. "
                    "The same scenario and seed give the same digest, bit for bit.")
    p.add_argument("scenario", type=Path, nargs="?",
                   help="scenario YAML file, e.g. scenarios/nav.yaml (not with --replay)")
    p.add_argument("--replay", type=Path, metavar="RUN_DIR",
                   help="run a recorded run again in lockstep: its scenario, and every message\n"
                        "that entered it from outside at the tick it entered; exit 4 when\n"
                        "the digest differs from the record's")
    p.add_argument("--in-process", action="store_true",
                   help="run every node in this process with no transport (the reference)")
    p.add_argument("--out", type=Path, default=Path("runs"),
                   help="directory that receives the run directory (default: runs)")
    p.add_argument("--transport", choices=TRANSPORTS,
                   help="override the scenario's transport")
    p.add_argument("--seed", type=int, help="override the scenario's seed")
    p.add_argument("--duration", help="override the scenario's duration, e.g. 10s")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override any scenario key, e.g. nodes.control.params.max_speed=0.4")
    p.add_argument("--quiet", action="store_true", help="print only the final line")
    p.add_argument("--domain", metavar="ID",
                   help="the ROS domain of the run (default: ROS_DOMAIN_ID when set, else a\n"
                        "free one of its own, printed); discovery stays on this machine\n"
                        "unless ROS_AUTOMATIC_DISCOVERY_RANGE says otherwise")
    p.add_argument("--strict", action="store_true",
                   help="refuse a scenario that has warnings (a goal the controller's map\n"
                        "cannot reach, an output nobody reads, ...): exit 2, nothing started")
    p.add_argument("--paused", action="store_true",
                   help="start paused: play or step with the simulation_interfaces services\n"
                        "/set_simulation_state, /step_simulation (ros2 runs)")
    p.add_argument("--sim-namespace", metavar="NS",
                   help="serve simulation_interfaces under NS (e.g. /cosim:\n"
                        "/cosim/step_simulation, as Gazebo under /gzserver) instead of the\n"
                        "root names Isaac Sim and O3DE use (simulation_interfaces.namespace)")
    p.add_argument("--export-usd", action="store_true",
                   help="also write the run as an OpenUSD stage, run.usda, with time-sampled\n"
                        "body transforms (usdview, Omniverse), and a URDF or USD robot as\n"
                        "robots/ROBOT.usda in Isaac Sim's importer layout; built from the bag\n"
                        "afterwards")
    p.add_argument("--expect-digest", metavar="HEX",
                   help="exit 4 unless the run's digest is HEX (64 hex digits)")
    p.add_argument("--against", type=Path, metavar="DIR",
                   help="a recorded run directory: on a digest mismatch, name the first topic\n"
                        "and tick that differ from it; its digest is expected unless\n"
                        "--expect-digest is given")
    p.add_argument("--ignore-rendered", action="store_true",
                   help="--expect-digest and --against compare the digest without the\n"
                        "rendered topics (camera images: their pixels depend on the GL\n"
                        "renderer and its version); the message names the topics left out")
    p.add_argument("--rendered-psnr", type=float, metavar="DB",
                   help="with --against: compare the rest as --ignore-rendered does, and the\n"
                        "rendered images frame by frame, each at least DB dB PSNR against\n"
                        "the reference run's (exit 4 below it, naming the frame)")
    live = p.add_argument_group("watch and drive the run from outside (loopback unless an "
                                "address is given)")
    live.add_argument("--live", nargs="?", const="127.0.0.1:8765", metavar="ADDR:PORT",
                      help="a Foxglove WebSocket server streaming every topic (CDR) with sim\n"
                           "time; pause/step/resume as services and playback controls\n"
                           "(default 127.0.0.1:8765; the digest is the same with or without)")
    live.add_argument("--rosbridge", nargs="?", const="127.0.0.1:9090", metavar="ADDR:PORT",
                      help="a rosbridge v2 server for roslibpy/roslibjs: subscribe to topics,\n"
                           "publish the scenario's external: topics (entering at a tick,\n"
                           "recorded), call the run's services (default 127.0.0.1:9090)")
    live.add_argument("--twin", metavar="ws://HOST:PORT",
                      help="a digital twin of the real robot whose rosbridge server this is:\n"
                           "the scenario's twin: topic map, paced on the wall clock (the\n"
                           "scenario's twin.url if not given)")
    how = p.add_argument_group("how the work is done (never changes the digest)")
    how.add_argument("--no-pipeline", action="store_true",
                     help="every node finishes tick k before /clock says k+1 (strict lockstep)")
    how.add_argument("--spawn", choices=SPAWN_MODES, default="fork",
                     help="start cosim nodes as forks of this process (default) or as fresh\n"
                          "interpreters")
    how.add_argument("--no-zenoh-shm", action="store_true",
                     help="zenoh: no shared memory for large messages")
    how.add_argument("--zenoh-express", action="store_true",
                     help="zenoh: write every message at once (no batching of messages\n"
                          "published back to back; costs more CPU per tick)")
    how.add_argument("--no-camera-warm-up", action="store_true",
                     help="cameras build their GL renderer at the first frame, not at set-up")
    how.add_argument("--pack", choices=PACKINGS,
                     help="which nodes share a process: each node alone, a robot's nodes\n"
                          "together, each kind's nodes together (default: the scenario's\n"
                          "process: keys, else each node alone)")
    how.add_argument("--spread", type=int, metavar="N",
                     help="with --pack kind: each kind's nodes over at most N processes\n"
                          "(a swarm's lidars and controllers on N cores)")
    how.add_argument("--real-time-factor", type=_real_time_factor, metavar="R",
                     help="pace the run for people: tick k starts no earlier than its sim\n"
                          "time / R after the first (1.0: real time, as Gazebo's default;\n"
                          "a MoveIt or rclpy client in another shell needs it to see the run).\n"
                          "Only the tick loop waits: the digest is the unpaced one. Default:\n"
                          "as fast as it goes")
    how.add_argument("--no-picture", action="store_true",
                     help="draw no report.png after the run (about a CPU second saved: for\n"
                          "suites of many short runs)")
    how.add_argument("--profile", choices=PROFILE_MODES,
                     help="write a cProfile of every cosim node into the run's logs/")
    p.add_argument("--shuffle-start", type=int, metavar="SEED", help=argparse.SUPPRESS)
    return p


def options_from(args: argparse.Namespace, on_tick=None):
    """The run options the command line asks for."""
    from plan.options import RunOptions

    return RunOptions(out=args.out, in_process=args.in_process, paused=args.paused,
                      export_usd=args.export_usd, pipeline=not args.no_pipeline,
                      spawn=args.spawn, zenoh_shm=not args.no_zenoh_shm,
                      zenoh_express=args.zenoh_express,
                      camera_warm_up=not args.no_camera_warm_up, profile=args.profile,
                      pack=args.pack, spread=args.spread, shuffle_start=args.shuffle_start,
                      strict=args.strict,
                      live=args.live, rosbridge=args.rosbridge, twin=args.twin,
                      real_time_factor=args.real_time_factor, picture=not args.no_picture)


def _real_time_factor(text: str) -> float:
    """--real-time-factor's value: a number above 0 (argparse's exit 2 otherwise)."""
    from plan.options import check_real_time_factor

    try:
        return check_real_time_factor(text, "")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).strip()) from None


def overrides_from(args: argparse.Namespace) -> dict:
    """Scenario overrides collected from the options."""
    from plan.overrides import parse_overrides

    overrides = parse_overrides(args.set)
    if args.transport:
        overrides["transport"] = args.transport
    if args.seed is not None:
        overrides["seed"] = args.seed
    if args.duration:
        overrides["duration"] = args.duration
    if args.sim_namespace is not None:
        overrides["simulation_interfaces.namespace"] = args.sim_namespace
    return overrides


def _images_pass(args: argparse.Namespace, outcome) -> bool:
    """--rendered-psnr: every rendered frame at or above the floor against --against's;
    says how each rendered topic compared either way."""
    from orchestrator.outputs.diff import read_manifest
    from orchestrator.outputs.image_compare import lowest_psnr

    topics = set(outcome.rendered_topics) | set(read_manifest(args.against).get(
        "rendered_topics") or [])
    results = lowest_psnr(args.against, outcome.run_dir, sorted(topics))
    failed = [r for r in results if not r.passes(args.rendered_psnr)]
    lines = "; ".join(r.describe() for r in results) or "none in this run"
    verdict = "below" if failed else "at or above"
    print(f"cosim-orchestrate: rendered topics against {args.against}, {verdict} the PSNR "
          f"floor of {args.rendered_psnr:g} dB: {lines}", file=sys.stderr)
    return not failed


def _check_twin_has_robot(scenario, args: argparse.Namespace) -> None:
    """A scenario with a twin: section is a twin of a robot: refuse to run it with no robot to
    connect to (it would run to "success" mirroring nothing), unless rosbridge clients feed
    its external topics instead."""
    from plan.errors import ScenarioError

    twin = scenario.model.twin
    if twin is None or args.twin or twin.url or args.rosbridge:
        return
    raise ScenarioError(scenario.file, "twin", "the scenario is a digital twin (a twin: "
                        "section) but names no robot to connect to: no --twin and no twin.url.",
                        "--twin ws://HOST:PORT (the robot's rosbridge server) or twin.url; "
                        "to feed its external topics yourself instead, --rosbridge.")


def _choose_domain(args: argparse.Namespace, scenario, options):
    """The run's ROS domain (orchestrator.run_domain), set for it and its nodes; None for
    an in-process run (no transport). DomainInUse when a pinned one has a run already."""
    from orchestrator.run_domain import choose, parse_domain

    pinned = parse_domain(args.domain, "--domain") if args.domain is not None else None
    if options.in_process:
        return None
    label = args.replay or args.scenario
    return choose(pinned, f"cosim-orchestrate {label}")



@guarded("cosim-orchestrate")
def main(argv: list[str] | None = None) -> int:
    """Entry point of cosim-orchestrate."""
    if argv is None:  # a command (not a call from a program): its own ROS 2 libraries
        from runtime.ros_libraries import ensure_own_libraries

        ensure_own_libraries()
    args = build_parser().parse_args(argv)
    import nodes  # noqa: F401 - provides the node kinds to the plan (plan.kinds)
    from descriptions.load import load_scenario
    from orchestrator.outputs.diff import (
        digest_mismatch,
        expected_digest,
        left_out_text,
        read_manifest,
    )
    from orchestrator.run_domain import DomainInUse
    from orchestrator.run_rules import check_run
    from plan.errors import ScenarioError

    recorded = None
    try:
        if (args.scenario is None) == (args.replay is None):
            raise ValueError("give a scenario file or --replay RUN_DIR (one of them)")
        if args.replay is not None:
            from orchestrator.replay import load_recorded

            if args.twin:
                raise ValueError("--replay feeds the recorded inputs; it takes no --twin")
            recorded = load_recorded(args.replay, overrides_from(args))
            scenario = recorded.scenario
        else:
            scenario = load_scenario(args.scenario, overrides_from(args))
            _check_twin_has_robot(scenario, args)
        if args.rendered_psnr is not None:
            if args.against is None:
                raise ValueError("--rendered-psnr needs --against DIR (a recorded run whose "
                                 "images are the reference)")
            if not args.rendered_psnr > 0:
                raise ValueError(f"--rendered-psnr {args.rendered_psnr}: expected a floor in "
                                 "dB above 0, e.g. 40")
            args.ignore_rendered = True
        expected = expected_digest(args.expect_digest, args.against, args.ignore_rendered)
        if recorded is not None and expected is None:
            expected = recorded.digest  # a twin's too: its inputs entered at recorded ticks
        options = options_from(args)
        warnings = check_run(scenario, options)  # execute applies it too; here: before output
        domain = _choose_domain(args, scenario, options)
    except (ScenarioError, ValueError, DomainInUse) as exc:
        print(f"cosim-orchestrate: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    for warning in warnings:
        print(f"cosim-orchestrate: warning: {warning}", file=sys.stderr)
    if domain is not None and not args.quiet:
        head, *commands = domain.lines(scenario.model.transport)
        print(f"cosim-orchestrate: {head}", file=sys.stderr)
        for command in commands:  # alone on its line: to paste as it is
            print(f"  {command}", file=sys.stderr)
    if recorded is not None:
        print(f"cosim-orchestrate: replaying {args.replay}: {recorded.count} message(s) from "
              f"outside at their ticks; recorded digest {recorded.digest}", file=sys.stderr)
    interruptible()  # SIGINT and SIGTERM: exit 130, even if started with them ignored
    from orchestrator.execute import execute
    from orchestrator.outputs.report import print_outcome
    from orchestrator.progress import Progress

    progress = Progress(scenario.schedule.n_ticks, scenario.tick_ns,
                        enabled=not args.quiet and sys.stderr.isatty())
    try:
        outcome = execute(scenario, options, on_tick=progress.update, external=recorded)
    except KeyboardInterrupt:
        print("cosim-orchestrate: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        progress.close()
    print_outcome(outcome, quiet=args.quiet)
    if outcome.unfinished:
        print(f"cosim-orchestrate: {outcome.unfinished}", file=sys.stderr)
    code = {"success": EXIT_SUCCESS, "goal_not_met": EXIT_GOAL_NOT_MET,
            "interrupted": EXIT_INTERRUPTED,
            "write_failed": EXIT_WRITE_FAILED}.get(outcome.status, EXIT_NODE_FAILED)
    if args.ignore_rendered and outcome.digest:
        value = read_manifest(outcome.run_dir).get("digest_without_rendered")
        print(f"cosim-orchestrate: digest {left_out_text(outcome.rendered_topics)}: {value}",
              file=sys.stderr)
    if expected and outcome.digest and code in (EXIT_SUCCESS, EXIT_GOAL_NOT_MET):
        mismatch = digest_mismatch(expected, outcome.run_dir, args.against or args.replay,
                                   args.ignore_rendered)
        if mismatch:
            print(f"cosim-orchestrate: {mismatch}", file=sys.stderr)
            return EXIT_DIGEST_MISMATCH
        if args.rendered_psnr is not None and not _images_pass(args, outcome):
            return EXIT_DIGEST_MISMATCH
    return code


if __name__ == "__main__":
    sys.exit(main())
