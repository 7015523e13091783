"""The cosim-ros2 command: ros2cli's everyday verbs, each group in its own module."""

from __future__ import annotations

import argparse
import sys

from orchestrator.ros2cli import action, control, param, service, topic
from orchestrator.ros2cli.attach import domain_to_use

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130
GROUPS = {"topic": topic, "service": service, "action": action, "param": param,
          "control": control}


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface: cosim-ros2 GROUP VERB ..., as ros2 GROUP VERB ..."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--domain", type=int, metavar="ID",
                        help="the ROS domain (default: ROS_DOMAIN_ID; without it, the "
                             "domain of the cosim run going on this machine, else 0)")
    p = argparse.ArgumentParser(
        prog="cosim-ros2",
        description="ros2cli's everyday verbs for a pip-only install (the ROS 2 wheels have "
                    "no ros2 command), with its arguments: YAML values such as "
                    "\"{linear: {x: 0.5}}\", types as pkg/msg/Name or pkg/Name. With a full "
                    "ROS 2 install, ros2 works the same.")
    groups = p.add_subparsers(dest="group", required=True, metavar="GROUP")
    for name, module in GROUPS.items():
        group = groups.add_parser(name, help=f"ros2 {name}'s verbs")
        verbs = group.add_subparsers(dest="verb", required=True, metavar="VERB")
        module.add_verbs(verbs, common)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of cosim-ros2."""
    if argv is None:  # a command (not a call from a program): its own ROS 2 libraries
        from runtime.ros_libraries import ensure_own_libraries

        ensure_own_libraries()
    args = build_parser().parse_args(argv)
    args.domain = domain_to_use(args.domain)
    try:
        return args.func(args)
    except ValueError as exc:
        print(f"cosim-ros2: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # the reader went away (| head): nothing more to say
        sys.stderr.close()
        return EXIT_OK
    except KeyboardInterrupt:
        return EXIT_OK if args.verb in ("echo", "hz", "pub") else EXIT_INTERRUPTED
