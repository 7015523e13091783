"""cosim-ros2 service: list and call, with ros2 service's arguments."""

from __future__ import annotations

import argparse
import sys

from orchestrator.ros2cli.messages import fill, interface_class, parse_values, to_yaml
from orchestrator.ros2cli.session import print_names, ros_session, spin_for, spin_until


def add_verbs(sub: argparse._SubParsersAction, common: argparse.ArgumentParser) -> None:
    """The service verbs on ``sub``."""
    p = sub.add_parser("list", parents=[common], help="the services on the ROS graph")
    p.add_argument("-t", "--show-types", action="store_true", help="each service's type too")
    p.add_argument("-a", "--include-hidden-services", action="store_true",
                   help="also services whose name has a part starting with _")
    p.add_argument("--spin-time", type=float, default=1.0, metavar="S",
                   help="seconds to wait for discovery before answering (default 1)")
    p.set_defaults(func=service_list)

    p = sub.add_parser("call", parents=[common], help="call a service and print its response")
    p.add_argument("service_name", help="e.g. /get_simulator_features")
    p.add_argument("service_type", help="e.g. std_srvs/srv/Trigger or std_srvs/Trigger")
    p.add_argument("values", nargs="?", default="",
                   help="the request's fields in YAML, e.g. \"{steps: 10}\"")
    p.add_argument("--timeout", type=float, default=30.0, metavar="S",
                   help="give up (exit 1) when no server answers within S seconds")
    p.set_defaults(func=service_call)


def service_list(args: argparse.Namespace) -> int:
    """Print the services (and their types)."""
    with ros_session(args.domain) as (node, executor):
        spin_for(executor, args.spin_time)
        print_names(node.get_service_names_and_types(), args.show_types,
                    args.include_hidden_services)
    return 0


def service_call(args: argparse.Namespace) -> int:
    """Call the service once with the request given in YAML; print request and response."""
    cls = interface_class(args.service_type, "srv")
    request = fill(cls.Request(), parse_values(args.values))
    with ros_session(args.domain) as (node, executor):
        client = node.create_client(cls, args.service_name)
        if not spin_until(executor, client.service_is_ready, args.timeout):
            print(f"no server of {args.service_name} within {args.timeout:g} s",
                  file=sys.stderr)
            return 1
        spin_for(executor, 0.2)  # the server's reply path may be matched a moment later
        print(f"requester: making request:\n{to_yaml(request)}\n", flush=True)
        future = client.call_async(request)
        if not spin_until(executor, future.done, args.timeout):
            print(f"{args.service_name} did not answer within {args.timeout:g} s",
                  file=sys.stderr)
            return 1
        print(f"response:\n{to_yaml(future.result())}")
    return 0
