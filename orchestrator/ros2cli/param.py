"""cosim-ros2 param: list, get and set, with ros2 param's arguments."""

from __future__ import annotations

import argparse
import sys
from typing import Any

import yaml

from orchestrator.ros2cli.session import ros_session, spin_until

# rcl_interfaces/msg/ParameterType -> (the word ros2 param get prints, the value's field)
KINDS = {1: ("Boolean", "bool_value"), 2: ("Integer", "integer_value"),
         3: ("Double", "double_value"), 4: ("String", "string_value"),
         5: ("Byte values", "byte_array_value"), 6: ("Boolean values", "bool_array_value"),
         7: ("Integer values", "integer_array_value"),
         8: ("Double values", "double_array_value"),
         9: ("String values", "string_array_value")}


def add_verbs(sub: argparse._SubParsersAction, common: argparse.ArgumentParser) -> None:
    """The param verbs on ``sub``."""
    p = sub.add_parser("list", parents=[common], help="a node's parameter names")
    p.add_argument("node_name", help="e.g. /control")
    _timeout(p)
    p.set_defaults(func=param_list)

    p = sub.add_parser("get", parents=[common], help="a parameter's value")
    p.add_argument("node_name", help="e.g. /control")
    p.add_argument("parameter_name", help="e.g. max_speed")
    _timeout(p)
    p.set_defaults(func=param_get)

    p = sub.add_parser("set", parents=[common], help="set a parameter")
    p.add_argument("node_name", help="e.g. /control")
    p.add_argument("parameter_name", help="e.g. max_speed")
    p.add_argument("value", help="in YAML: 0.3, true, text, [1, 2]")
    _timeout(p)
    p.set_defaults(func=param_set)


def _timeout(p: argparse.ArgumentParser) -> None:
    """--timeout: how long to wait for the node's parameter services."""
    p.add_argument("--timeout", type=float, default=10.0, metavar="S",
                   help="seconds to wait for the node's parameter services (default 10)")


def _client(node: Any, executor: Any, args: argparse.Namespace) -> Any:
    """A parameter client of the named node once its services are there (None if never)."""
    from rclpy.parameter_client import AsyncParameterClient

    client = AsyncParameterClient(node, args.node_name)
    ready = spin_until(executor, lambda: client.services_are_ready(), args.timeout)
    if not ready:
        print(f"Node not found: {args.node_name} (no parameter services within "
              f"{args.timeout:g} s)", file=sys.stderr)
        return None
    return client


def _answer(executor: Any, future: Any, timeout: float) -> Any:
    """The result of a parameter service call (None when it did not answer in time)."""
    return future.result() if spin_until(executor, future.done, timeout) else None


def param_list(args: argparse.Namespace) -> int:
    """Print a node's parameter names, one a line, indented as ros2 param list does."""
    with ros_session(args.domain) as (node, executor):
        client = _client(node, executor, args)
        answer = client and _answer(executor, client.list_parameters(), args.timeout)
        if answer is None:
            return 1
        for name in sorted(answer.result.names):
            print(f"  {name}")
    return 0


def param_get(args: argparse.Namespace) -> int:
    """Print '<Kind> value is: <value>' as ros2 param get does."""
    with ros_session(args.domain) as (node, executor):
        client = _client(node, executor, args)
        answer = client and _answer(executor, client.get_parameters([args.parameter_name]),
                                    args.timeout)
        if answer is None:
            return 1
        value = answer.values[0] if answer.values else None
        if value is None or value.type not in KINDS:
            print("Parameter not set.")
            return 1
        word, field = KINDS[value.type]
        shown = getattr(value, field)
        if isinstance(shown, bool):
            shown = str(shown)
        elif not isinstance(shown, int | float | str):
            shown = list(shown)
        print(f"{word} value is: {shown}")
    return 0


def param_set(args: argparse.Namespace) -> int:
    """Set a parameter (its type from the YAML value); print whether the node took it."""
    from rclpy.parameter import Parameter

    value = yaml.safe_load(args.value)
    with ros_session(args.domain) as (node, executor):
        client = _client(node, executor, args)
        answer = client and _answer(
            executor, client.set_parameters([Parameter(args.parameter_name, value=value)]),
            args.timeout)
        if answer is None:
            return 1
        result = answer.results[0]
        if result.successful:
            print("Set parameter successful")
            return 0
        print(f"Setting parameter failed: {result.reason}")
        return 1
