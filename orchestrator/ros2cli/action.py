"""cosim-ros2 action: list and send_goal, with ros2 action's arguments."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from orchestrator.ros2cli.messages import fill, interface_class, parse_values, to_yaml
from orchestrator.ros2cli.session import print_names, ros_session, spin_for, spin_until

STATUS = {0: "UNKNOWN", 1: "ACCEPTED", 2: "EXECUTING", 3: "CANCELING", 4: "SUCCEEDED",
          5: "CANCELED", 6: "ABORTED"}  # action_msgs/msg/GoalStatus


def add_verbs(sub: argparse._SubParsersAction, common: argparse.ArgumentParser) -> None:
    """The action verbs on ``sub``."""
    p = sub.add_parser("list", parents=[common], help="the actions on the ROS graph")
    p.add_argument("-t", "--show-types", action="store_true", help="each action's type too")
    p.add_argument("--spin-time", type=float, default=1.0, metavar="S",
                   help="seconds to wait for discovery before answering (default 1)")
    p.set_defaults(func=action_list)

    p = sub.add_parser("send_goal", parents=[common],
                       help="send a goal and wait for its result")
    p.add_argument("action_name", help="e.g. /navigate_to_pose")
    p.add_argument("action_type",
                   help="e.g. nav2_msgs/action/NavigateToPose or nav2_msgs/NavigateToPose")
    p.add_argument("goal", nargs="?", default="",
                   help="the goal's fields in YAML, e.g. \"{steps: 10}\"")
    p.add_argument("-f", "--feedback", action="store_true", help="print the feedback too")
    p.add_argument("--timeout", type=float, metavar="S",
                   help="give up (exit 1) when there is no server or no result within S "
                        "seconds (default: wait)")
    p.set_defaults(func=send_goal)


def action_list(args: argparse.Namespace) -> int:
    """Print the actions (and their types)."""
    from rclpy.action import get_action_names_and_types

    with ros_session(args.domain) as (node, executor):
        spin_for(executor, args.spin_time)
        print_names(get_action_names_and_types(node), args.show_types)
    return 0


def send_goal(args: argparse.Namespace) -> int:
    """Send one goal; print its id, the feedback if asked, the result and the final status."""
    from rclpy.action import ActionClient

    cls = interface_class(args.action_type, "action")
    goal = fill(cls.Goal(), parse_values(args.goal))
    with ros_session(args.domain) as (node, executor):
        def feedback(msg: Any) -> None:
            print(f"Feedback:\n{to_yaml(msg.feedback)}\n", flush=True)

        client = ActionClient(node, cls, args.action_name)
        print("Waiting for an action server to become available...", flush=True)
        if not spin_until(executor, client.server_is_ready, args.timeout):
            print(f"no server of {args.action_name}", file=sys.stderr)
            return 1
        spin_for(executor, 0.2)  # the server's reply path may be matched a moment later
        print(f"Sending goal:\n{to_yaml(goal)}\n", flush=True)
        sent = client.send_goal_async(goal, feedback_callback=feedback if args.feedback
                                      else None)
        if not spin_until(executor, sent.done, args.timeout):
            print("the server did not answer the goal", file=sys.stderr)
            return 1
        handle = sent.result()
        if not handle.accepted:
            print("Goal was rejected.")
            return 1
        print(f"Goal accepted with ID: {bytes(handle.goal_id.uuid).hex()}\n", flush=True)
        result = handle.get_result_async()
        if not spin_until(executor, result.done, args.timeout):
            print("no result in time", file=sys.stderr)
            return 1
        answer = result.result()
        print(f"Result:\n{to_yaml(answer.result)}\n")
        print(f"Goal finished with status: {STATUS.get(answer.status, answer.status)}")
        return 0 if answer.status == 4 else 1
