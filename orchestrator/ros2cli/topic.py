"""cosim-ros2 topic: list, info, echo, hz, pub, with ros2 topic's arguments."""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

from orchestrator.ros2cli.messages import (
    fill,
    interface_class,
    parse_values,
    to_yaml,
    type_name,
)
from orchestrator.ros2cli.session import (
    matching_qos,
    print_names,
    ros_session,
    spin_for,
    spin_until,
    wait_for_topic_type,
)


def add_verbs(sub: argparse._SubParsersAction, common: argparse.ArgumentParser) -> None:
    """The topic verbs on ``sub`` (``common``: the options every verb takes)."""
    p = sub.add_parser("list", parents=[common], help="the topics on the ROS graph")
    p.add_argument("-t", "--show-types", action="store_true", help="each topic's type too")
    p.add_argument("-a", "--include-hidden-topics", action="store_true",
                   help="also topics whose name has a part starting with _")
    _spin_time(p)
    p.set_defaults(func=topic_list)

    p = sub.add_parser("info", parents=[common], help="a topic's type and its endpoints")
    p.add_argument("topic_name", help="e.g. /odom")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="each publisher's and subscriber's node and QoS")
    _spin_time(p)
    p.set_defaults(func=topic_info)

    p = sub.add_parser("echo", parents=[common], help="print a topic's messages as YAML")
    p.add_argument("topic_name", help="e.g. /odom")
    p.add_argument("message_type", nargs="?",
                   help="e.g. nav_msgs/msg/Odometry (default: the type on the graph)")
    p.add_argument("--once", action="store_true", help="print one message and exit")
    p.add_argument("--timeout", type=float, metavar="S",
                   help="give up (exit 1) when nothing arrives within S seconds")
    p.add_argument("--field", metavar="NAME", help="print only this field, e.g. pose.pose")
    p.set_defaults(func=topic_echo)

    p = sub.add_parser("hz", parents=[common], help="a topic's publishing rate")
    p.add_argument("topic_name", help="e.g. /odom")
    p.add_argument("-w", "--window", type=int, default=10000,
                   help="how many of the latest messages the statistics cover")
    p.add_argument("--duration", type=float, metavar="S",
                   help="exit after S seconds (default: run until Ctrl-C)")
    p.set_defaults(func=topic_hz)

    p = sub.add_parser("pub", parents=[common], help="publish a message")
    p.add_argument("topic_name", help="e.g. /cmd_vel")
    p.add_argument("message_type", help="e.g. geometry_msgs/msg/Twist or geometry_msgs/Twist")
    p.add_argument("values", nargs="?", default="",
                   help='the message\'s fields in YAML, e.g. "{linear: {x: 0.5}}"')
    p.add_argument("-r", "--rate", type=float, default=1.0,
                   help="publishing rate in Hz (default 1)")
    p.add_argument("-p", "--print", type=int, default=1, metavar="N", dest="print_nth",
                   help="print every Nth published message (0: none)")
    p.add_argument("-1", "--once", action="store_true", help="publish one message and exit")
    p.add_argument("-t", "--times", type=int, default=0,
                   help="publish this many messages and exit")
    p.add_argument("-w", "--wait-matching-subscriptions", type=int, metavar="N",
                   help="wait for N subscribers before publishing (default 1 with --once or "
                        "--times, else 0)")
    p.add_argument("--keep-alive", type=float, default=0.1, metavar="S",
                   help="after the last message, stay S seconds so it is delivered")
    p.set_defaults(func=topic_pub)


def _spin_time(p: argparse.ArgumentParser) -> None:
    """--spin-time: how long to listen for discovery before answering."""
    p.add_argument("--spin-time", type=float, default=1.0, metavar="S",
                   help="seconds to wait for discovery before answering (default 1)")


def topic_list(args: argparse.Namespace) -> int:
    """Print the topics (and their types)."""
    with ros_session(args.domain) as (node, executor):
        spin_for(executor, args.spin_time)
        print_names(node.get_topic_names_and_types(), args.show_types,
                    args.include_hidden_topics)
    return 0


def topic_info(args: argparse.Namespace) -> int:
    """Print a topic's type and how many publish and subscribe to it."""
    with ros_session(args.domain) as (node, executor):
        spin_for(executor, args.spin_time)
        types = dict(node.get_topic_names_and_types()).get(args.topic_name)
        if not types:
            print(f"Unknown topic '{args.topic_name}'", file=sys.stderr)
            return 1
        pubs = node.get_publishers_info_by_topic(args.topic_name)
        subs = node.get_subscriptions_info_by_topic(args.topic_name)
        print(f"Type: {', '.join(types)}")
        for label, infos in (("Publisher", pubs), ("Subscription", subs)):
            print(f"{label} count: {len(infos)}")
            if args.verbose:
                for info in infos:
                    qos = info.qos_profile
                    print(f"\nNode name: {info.node_name}\nNode namespace: "
                          f"{info.node_namespace}\nTopic type: {info.topic_type}\n"
                          f"Endpoint type: {info.endpoint_type.name}\nQoS profile:\n"
                          f"  Reliability: {qos.reliability.name}\n"
                          f"  Durability: {qos.durability.name}\n  Depth: {qos.depth}\n")
    return 0


def topic_echo(args: argparse.Namespace) -> int:
    """Print each message of a topic as YAML, separated by ---."""
    with ros_session(args.domain) as (node, executor):
        name = args.message_type or wait_for_topic_type(node, executor, args.topic_name,
                                                        args.timeout, _note)
        if name is None:
            print(f"nothing publishes {args.topic_name} (waited {args.timeout:g} s)",
                  file=sys.stderr)
            return 1
        cls = interface_class(name, "msg")
        received: list[Any] = []
        # wait for a publisher, so the QoS is one it can serve
        spin_until(executor, lambda: node.count_publishers(args.topic_name) > 0, args.timeout)
        node.create_subscription(cls, args.topic_name, received.append,
                                 matching_qos(node, args.topic_name))
        while True:
            if not spin_until(executor, lambda: bool(received), args.timeout):
                print(f"no message on {args.topic_name} within {args.timeout:g} s",
                      file=sys.stderr)
                return 1
            msg = received.pop(0)
            print(_field(msg, args.field) if args.field else to_yaml(msg))
            print("---", flush=True)
            if args.once:
                return 0


def _field(msg: Any, path: str) -> str:
    """One field of a message (a dotted path) as YAML or a plain value."""
    value = msg
    for part in path.split("."):
        value = getattr(value, part)
    return to_yaml(value) if hasattr(value, "get_fields_and_field_types") else str(value)


def topic_hz(args: argparse.Namespace) -> int:
    """Print the rate of a topic's messages once a second (on this machine's clock)."""
    with ros_session(args.domain) as (node, executor):
        name = wait_for_topic_type(node, executor, args.topic_name, args.duration, _note)
        if name is None:
            print(f"nothing publishes {args.topic_name}", file=sys.stderr)
            return 1
        stamps: list[float] = []

        def arrived(_msg: Any) -> None:
            stamps.append(time.monotonic())
            del stamps[:-args.window - 1]

        node.create_subscription(interface_class(name, "msg"), args.topic_name, arrived,
                                 matching_qos(node, args.topic_name))
        end = None if args.duration is None else time.monotonic() + args.duration
        while end is None or time.monotonic() < end:
            spin_for(executor, 1.0 if end is None else min(1.0, end - time.monotonic()))
            if len(stamps) < 2:
                print("no new messages", flush=True)
                continue
            gaps = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
            mean = sum(gaps) / len(gaps)
            std = math.sqrt(sum((g - mean) ** 2 for g in gaps) / len(gaps))
            print(f"average rate: {1 / mean:.3f}\n\tmin: {min(gaps):.3f}s max: "
                  f"{max(gaps):.3f}s std dev: {std:.5f}s window: {len(gaps)}", flush=True)
    return 0


def topic_pub(args: argparse.Namespace) -> int:
    """Publish the message at a rate, once or a number of times."""
    cls = interface_class(args.message_type, "msg")
    msg = fill(cls(), parse_values(args.values))
    times = 1 if args.once else args.times
    wait_for = args.wait_matching_subscriptions
    if wait_for is None:
        wait_for = 1 if times else 0
    with ros_session(args.domain) as (node, executor):
        publisher = node.create_publisher(cls, args.topic_name, 10)
        if wait_for:
            print(f"Waiting for at least {wait_for} matching subscription(s)...", flush=True)
            spin_until(executor, lambda: publisher.get_subscription_count() >= wait_for, None)
        print("publisher: beginning loop", flush=True)
        count = 0
        period = 1.0 / args.rate
        next_at = time.monotonic()
        while not times or count < times:
            publisher.publish(msg)
            count += 1
            if args.print_nth and count % args.print_nth == 0:
                print(f"publishing #{count}: {type_name(cls)}\n{to_yaml(msg)}\n", flush=True)
            if times and count >= times:
                break
            next_at += period
            spin_for(executor, max(0.0, next_at - time.monotonic()))
        spin_for(executor, args.keep_alive)
    return 0


def _note(text: str) -> None:
    """A word on stderr while a verb waits."""
    print(text, file=sys.stderr, flush=True)
