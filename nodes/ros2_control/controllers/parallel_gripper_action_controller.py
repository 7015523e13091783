"""parallel_gripper_action_controller/GripperActionController: a parallel gripper's joint
driven by ``~/gripper_cmd`` (control_msgs/action/ParallelGripperCommand), as MoveIt's
grasping drives it: a goal's one position becomes the joint's position command; the goal
succeeds when the joint is within ``goal_tolerance`` of it, and when it has not moved for
``stall_timeout`` (slower than ``stall_velocity_threshold``) it is stalled: succeeded with
``allow_stalling``, else aborted. A cancel holds the joint where it is; a deactivation holds
it and aborts the goal.

As the trajectory controller's, the action is served by the orchestrator (the manager's
face), whose goals and cancels enter here at a tick boundary on ``~/cosim/goal``
(ParallelGripperCommand_Goal, named in ``command.header.frame_id``: the protocol of
``nodes.ros2_control.goals``); the goal's state reaches the face as this controller's
metrics.
"""

from __future__ import annotations

import math
from typing import Any

from control_msgs.action import ParallelGripperCommand
from pydantic import Field

from nodes.ros2_control.goals import ABORTED, CANCELED, SUCCEEDED, GoalProtocol
from nodes.ros2_control.interface import (
    NS_PER_S,
    Claim,
    ControllerInterface,
    ControllerParams,
    Update,
)

GOAL, ACTION = "~/cosim/goal", "~/gripper_cmd"


class ParallelGripperParams(ControllerParams):
    """parallel_gripper_action_controller's parameters (its
    ``gripper_action_controller_parameters.yaml``)."""

    joint: str = Field(min_length=1, description="the gripper's joint")
    action_monitor_rate: float = Field(20.0, ge=0.1, description="Hz")
    state_interfaces: list[str] = ["position", "velocity"]
    goal_tolerance: float = Field(0.01, ge=0.0, description="rad or m, 0 or more")
    allow_stalling: bool = False
    stall_velocity_threshold: float = 0.001
    stall_timeout: float = Field(1.0, ge=0.0, description="seconds, 0 or more")
    max_effort_interface: str = Field("", description="the interface taking the goal's "
                                      "effort limit (joint/interface), or empty")
    max_effort: float = Field(10.0, ge=0.0, description="N or Nm, 0 or more")
    max_velocity_interface: str = Field("", description="the interface taking the goal's "
                                        "velocity limit (joint/interface), or empty")
    max_velocity: float = Field(0.1, ge=0.0, description="rad/s or m/s, 0 or more")


class ParallelGripperActionController(ControllerInterface):
    """Drives a gripper's joint to a goal's position; see the module."""

    Params = ParallelGripperParams

    def __init__(self, name: str, params: ParallelGripperParams):
        super().__init__(name, params)
        self.position_cmd = 0.0
        self.velocity_cmd = params.max_velocity
        self.effort_cmd = params.max_effort
        self.goal = GoalProtocol()
        self.stalled = False
        self.reached_goal = False
        self.result_position = 0.0
        self.last_movement_ns = 0

    def claim(self) -> Claim:
        """The joint's position command (and the limit interfaces named), its states."""
        p = self.params
        extra = tuple(i for i in (p.max_velocity_interface, p.max_effort_interface) if i)
        return Claim((f"{p.joint}/position", *extra),
                     tuple(f"{p.joint}/{i}" for i in p.state_interfaces))

    def subscriptions(self) -> dict[str, type]:
        """The action's goals and cancels."""
        return {GOAL: ParallelGripperCommand.Goal}

    def actions(self) -> dict[str, type]:
        """``~/gripper_cmd``."""
        return {ACTION: ParallelGripperCommand}

    def metrics(self) -> dict[str, float]:
        """The newest goal: number, state, result code, whether a deactivation ended it,
        whether it stalled or reached its goal, and the joint's position when it ended."""
        return {**self.goal.metrics(), "stalled": float(self.stalled),
                "reached_goal": float(self.reached_goal), "position": self.result_position}

    def on_activate(self) -> Update:
        """Hold the joint where it is."""
        self._hold()
        self.result_position = self.position_cmd
        return Update()

    def on_deactivate(self) -> Update:
        """Hold the joint where it is; an executing goal is aborted, as upstream's."""
        self._hold()
        if self.goal.deactivate():
            self.result_position = self.position_cmd
        return Update()

    def _hold(self) -> None:
        self.position_cmd = self.state[self.params.joint].position
        self.velocity_cmd, self.effort_cmd = self.params.max_velocity, self.params.max_effort

    def on_message(self, topic: str, msg: Any, time_ns: int) -> list[str]:
        """A goal (its one position, velocity and effort limits) or a cancel."""
        command = msg.command
        name = command.header.frame_id
        kind = GoalProtocol.kind(name)
        if kind is None:
            return []
        if kind == "cancel":
            if self.goal.end(CANCELED):
                self._hold()
            return []
        self.goal.begin(name)  # preempts the one executing
        self.stalled = self.reached_goal = False
        if len(command.position) != 1:
            self.goal.end(ABORTED)
            return [f"{self.name}/gripper_cmd goal {self.goal.goal_id} refused: "
                    f"{len(command.position)} positions, expects 1"]
        p = self.params
        self.position_cmd = float(command.position[0])
        self.velocity_cmd = (float(command.velocity[0]) if p.max_velocity_interface
                             and len(command.velocity) else p.max_velocity)
        self.effort_cmd = (float(command.effort[0]) if p.max_effort_interface
                           and len(command.effort) else p.max_effort)
        self.last_movement_ns = time_ns
        return []

    def update(self, time_ns: int, period_ns: int) -> Update:
        """Check the goal, then command the position (and the limits claimed)."""
        p = self.params
        reading = self.state[p.joint]
        if self.goal.executing:
            if math.fabs(self.position_cmd - reading.position) < p.goal_tolerance:
                self._end(SUCCEEDED, reached=True, position=reading.position)
            elif math.fabs(reading.velocity) > p.stall_velocity_threshold:
                self.last_movement_ns = time_ns
            elif time_ns - self.last_movement_ns > round(p.stall_timeout * NS_PER_S):
                self.stalled = True
                self._end(SUCCEEDED if p.allow_stalling else ABORTED, reached=False,
                          position=reading.position)
        commands = {f"{p.joint}/position": self.position_cmd}
        if p.max_velocity_interface:
            commands[p.max_velocity_interface] = self.velocity_cmd
        if p.max_effort_interface:
            commands[p.max_effort_interface] = self.effort_cmd
        return Update(commands)

    def _end(self, outcome: int, reached: bool, position: float) -> None:
        self.goal.end(outcome)
        self.reached_goal, self.result_position = reached, position
