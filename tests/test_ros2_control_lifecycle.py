"""Controllers across deactivation and reactivation, as upstream's: an executing action goal
is aborted when its controller is deactivated; goals are known by the face's number."""

from __future__ import annotations

from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory, ParallelGripperCommand
from trajectory_msgs.msg import JointTrajectoryPoint

from nodes.ros2_control.goals import ABORTED, DEACTIVATED, INVALID_GOAL
from nodes.ros2_control.interface import JointReading
from nodes.ros2_control.registry import controller_class
from orchestrator.ros_surface.controller_actions import (
    FollowJointTrajectoryFace,
    ParallelGripperFace,
)

JTC = "joint_trajectory_controller/JointTrajectoryController"
GRIPPER = "parallel_gripper_action_controller/GripperActionController"


def trajectory_goal(name: str, joints: list[str], target: float):
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.header.frame_id = name
    goal.trajectory.joint_names = joints
    goal.trajectory.points = [JointTrajectoryPoint(positions=[target] * len(joints),
                                                   time_from_start=Duration(sec=2))]
    return goal


def gripper_goal(name: str, position: float):
    goal = ParallelGripperCommand.Goal()
    goal.command.header.frame_id = name
    goal.command.position = [position]
    return goal


def active(kind: str, state: dict, **params):
    cls = controller_class(kind)
    ctrl = cls(kind.split("/")[0], cls.Params(**params))
    ctrl.configure()
    ctrl.activate(state)
    return ctrl


def test_a_deactivation_aborts_the_executing_goal_of_either_action_controller():
    state = {"a": JointReading(0.4), "b": JointReading(-0.2)}
    jtc = active(JTC, state, joints=["a", "b"], command_interfaces=["position"])
    assert jtc.on_message("~/cosim/goal", trajectory_goal("cosim-goal-7", ["a", "b"], 1.0),
                          0) == []
    jtc.update(10_000_000, 10_000_000)
    assert jtc.metrics()["goal_state"] == 1.0
    jtc.deactivate()
    m = jtc.metrics()
    assert (m["goal_seq"], m["goal_state"], m["error_code"], m["deactivated"]) == (
        7.0, ABORTED, INVALID_GOAL, 1.0)
    ending = FollowJointTrajectoryFace.ended(m["goal_state"], m, jtc, False)
    assert ending.how == "abort" and ending.text == DEACTIVATED
    assert ending.result.error_code == INVALID_GOAL and ending.result.error_string == DEACTIVATED

    gripper = active(GRIPPER, state, joint="a")
    gripper.on_message("~/cosim/goal", gripper_goal("cosim-goal-12", 0.0), 0)
    assert gripper.update(10_000_000, 10_000_000).commands == {"a/position": 0.0}
    gripper.deactivate()
    m = gripper.metrics()
    assert (m["goal_seq"], m["goal_state"], m["deactivated"]) == (12.0, ABORTED, 1.0)
    ending = ParallelGripperFace.ended(m["goal_state"], m, gripper, False)
    assert ending.how == "abort" and ending.text == DEACTIVATED
