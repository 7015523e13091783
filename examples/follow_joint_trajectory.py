"""A MoveIt user's script against a cosim run: plain rclpy, nothing of cosim imported.

It does what MoveIt's trajectory execution does with a ros2_control arm: lists the
controllers, activates the joint trajectory controller where it is not active
(switch_controller, as ``ros2 control switch_controllers --activate`` does), sends it one
FollowJointTrajectory goal and waits for the result. Run it in a shell that has the run's
ROS_DOMAIN_ID and discovery range (the line cosim-orchestrate printed), while the run plays
(docs/how-to/ros2-control.md):

    ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=42 \\
        .venv/bin/python examples/follow_joint_trajectory.py --ns /

``--ns``: the robot's namespace (``/`` for a lone robot, ``/robot_2`` in a swarm).
"""

from __future__ import annotations

import argparse
import sys

import rclpy
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory
from controller_manager_msgs.srv import ListControllers, SwitchController
from rclpy.action import ActionClient
from trajectory_msgs.msg import JointTrajectoryPoint

JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
          "wrist_2_joint", "wrist_3_joint"]
TARGET = [0.4, -0.9, 0.7, -0.8, 0.3, 0.5]


def call(node, srv_type, name: str, request, timeout: float):
    """One service call's response; None when the service never appears."""
    client = node.create_client(srv_type, name)
    if not client.wait_for_service(timeout_sec=timeout):
        return None
    answer = client.call_async(request)
    rclpy.spin_until_future_complete(node, answer, timeout_sec=timeout)
    return answer.result()


def main() -> int:
    """Activate the trajectory controller, send one goal, print its outcome; exit 0 when it
    succeeded."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ns", default="/", help="the robot's namespace")
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds to wait")
    args = parser.parse_args()
    ns = args.ns.rstrip("/")
    rclpy.init()
    node = rclpy.create_node("follow_joint_trajectory_client")
    try:
        listed = call(node, ListControllers, f"{ns}/controller_manager/list_controllers",
                      ListControllers.Request(), args.timeout)
        if listed is None:
            print("no controller manager: is the run going, on this ROS domain?")
            return 1
        states = {c.name: c.state for c in listed.controller}
        print(f"list_controllers: {states}")
        if states.get("joint_trajectory_controller") != "active":  # as MoveIt switches
            switched = call(node, SwitchController,
                            f"{ns}/controller_manager/switch_controller",
                            SwitchController.Request(
                                activate_controllers=["joint_trajectory_controller"],
                                strictness=SwitchController.Request.STRICT), args.timeout)
            print(f"switch_controller: ok={switched.ok} {switched.message!r}")

        action = ActionClient(node, FollowJointTrajectory,
                              f"{ns}/joint_trajectory_controller/follow_joint_trajectory")
        action.wait_for_server(timeout_sec=args.timeout)
        goal = FollowJointTrajectory.Goal()
        goal.trajectory.joint_names = JOINTS
        goal.trajectory.points = [
            JointTrajectoryPoint(positions=[v / 2 for v in TARGET],
                                 time_from_start=Duration(sec=1)),
            JointTrajectoryPoint(positions=TARGET, time_from_start=Duration(sec=2))]
        sent = action.send_goal_async(goal)
        rclpy.spin_until_future_complete(node, sent, timeout_sec=args.timeout)
        handle = sent.result()
        if handle is None or not handle.accepted:
            print("goal rejected (is joint_trajectory_controller active?)")
            return 1
        result = handle.get_result_async()
        rclpy.spin_until_future_complete(node, result, timeout_sec=args.timeout)
        if not result.done():
            print("no result: does the run play (not paused, not ended)?")
            return 1
        outcome = result.result()
        print(f"status {outcome.status}, error_code {outcome.result.error_code} "
              f"{outcome.result.error_string!r}")
        return 0 if outcome.result.error_code == FollowJointTrajectory.Result.SUCCESSFUL else 1
    finally:
        node.destroy_node()
        rclpy.shutdown()


if __name__ == "__main__":
    sys.exit(main())
