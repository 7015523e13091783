"""The joint_targets node: publishes a sequence of joint position targets for an arm.

Input: /joint_states (sensor_msgs/JointState, same_tick; the joints are found by name).
Output: /joint_commands (std_msgs/Float64MultiArray), one position per ``joints`` entry in
that order, as the physics node's ``position_joints`` take them; without ``joints``, the
robot model's position-commanded joints (``NodeConfig.robots``), in its order. Each target is
published for at least ``hold``, then until every joint is within ``tolerance`` of it; then the next
one. The last one stays. A /joint_states without one of the joints is noted (once) and the
target held.
"""

from __future__ import annotations

from typing import Any

import mujoco
from pydantic import BaseModel, ConfigDict, Field
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from descriptions.robot_model import RobotModel
from nodes.contract import StepNode, Tick
from nodes.physics.world import robots_of
from plan.model import DURATION_HELP, DurationNs
from plan.topic_names import JOINT_COMMANDS, JOINT_STATES

ONE_POSITION = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


class JointTargetsParams(BaseModel):
    """The joints commanded, the targets in order and how long each is held."""

    model_config = ConfigDict(extra="forbid")
    joints: list[str] | None = Field(None, min_length=1, description="joint names in the "
                                     "world, in command order; default: the robot model's "
                                     "position-commanded joints")
    targets: list[list[float]] = Field(min_length=1, description="positions (rad), one "
                                       "list per target with one entry per joint")
    hold: DurationNs = Field(1_000_000_000, gt=0, description=DURATION_HELP + "; the "
                             "least time each target is held")
    tolerance: float = Field(0.05, gt=0, description="rad: a target is reached when every "
                             "joint is this close to it")


class JointTargetsNode(StepNode):
    """A timed sequence of joint position targets on /joint_commands."""

    Params = JointTargetsParams
    needs_world = True  # the joints and their ranges are checked against it at load

    @classmethod
    def outputs(cls, params: JointTargetsParams) -> dict[str, type]:
        """/joint_commands."""
        return {JOINT_COMMANDS: Float64MultiArray}

    @classmethod
    def accepted_inputs(cls, params: JointTargetsParams) -> set[str]:
        """/joint_states."""
        return {JOINT_STATES}

    @classmethod
    def input_types(cls, params: JointTargetsParams) -> dict[str, type]:
        """/joint_states as sensor_msgs/JointState."""
        return {JOINT_STATES: JointState}

    @classmethod
    def world_problems(cls, params: JointTargetsParams, model, goal
                       ) -> list[tuple[str, str, str]]:
        """Every joint is a hinge or slide joint of the world; every target has one position
        per joint, inside that joint's range (the joints given; without them, checked when
        the node is set up, against the robot model's)."""
        if params.joints is None:
            return []
        joints = {model.joint(j).name: j for j in range(model.njnt)
                  if int(model.jnt_type[j]) in ONE_POSITION}
        for n, name in enumerate(params.joints):
            if name not in joints:
                return [(f"params.joints[{n}]", f"the world has no hinge or slide joint "
                         f"{name!r}; its joints: {', '.join(j for j in joints if j) or 'none'}.",
                         "names of the arm's joints in the world.")]
        for n, target in enumerate(params.targets):
            if len(target) != len(params.joints):
                return [(f"params.targets[{n}]", f"{len(target)} positions for "
                         f"{len(params.joints)} joints {params.joints}.",
                         f"a list of {len(params.joints)} positions, one per joint in order.")]
            for name, value in zip(params.joints, target, strict=True):
                j = joints[name]
                low, high = model.jnt_range[j]
                if model.jnt_limited[j] and not low <= value <= high:
                    return [(f"params.targets[{n}]", f"{value} for joint {name!r} is outside "
                             f"its range [{low:g}, {high:g}].",
                             "positions inside the joints' ranges.")]
        return []

    @classmethod
    def robot_problems(cls, params: JointTargetsParams, robot: RobotModel, model: Any
                       ) -> list[tuple[str, str, str]]:
        """Without ``joints``, every target has one position per joint the robot commands
        by position, in the robot model's order."""
        if params.joints is not None:
            return []
        joints = commanded_joints(robot)
        for n, target in enumerate(params.targets):
            if len(target) != len(joints):
                return [(f"params.targets[{n}]", f"{len(target)} positions for the "
                         f"{len(joints)} joints the robot commands by position "
                         f"({', '.join(joints) or 'none'}).",
                         f"a list of {len(joints)} positions, one per joint in that order; or "
                         "params.joints naming the joints the targets are for.")]
        return []

    def setup(self) -> None:
        """The joints (given, or the robot model's), the commands, built once; the first
        target from time 0."""
        if self.params.joints is None:
            robots = robots_of(self.config, {})
            joints = commanded_joints(robots[0]) if len(robots) == 1 else []
            for n, target in enumerate(self.params.targets):
                if len(target) != len(joints):
                    raise ValueError(f"target {n} has {len(target)} positions; the robot "
                                     f"commands {len(joints)} joints {joints}")
            self.params = self.params.model_copy(update={"joints": joints})
        self.commands = [Float64MultiArray(data=[float(v) for v in t])
                         for t in self.params.targets]
        self.index = 0
        self.since_ns = 0
        self.missing_noted = False

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """The current target, after moving on to the next one if this one is reached."""
        last = len(self.commands) - 1
        if (self.index < last and tick.time_ns - self.since_ns >= self.params.hold
                and self._reached(inputs.get(JOINT_STATES))):
            self.index += 1
            self.since_ns = tick.time_ns
        return {JOINT_COMMANDS: self.commands[self.index]}

    def _reached(self, states: JointState | None) -> bool:
        if states is None:
            return False
        position = dict(zip(states.name, states.position, strict=False))
        missing = [j for j in self.params.joints if j not in position]
        if missing:
            if not self.missing_noted:
                self.missing_noted = True
                self.note(f"{JOINT_STATES} has no joint {missing[0]!r}; target "
                          f"{self.index} is held")
            return False
        target = self.params.targets[self.index]
        return all(abs(position[j] - t) <= self.params.tolerance
                   for j, t in zip(self.params.joints, target, strict=True))

    def metrics(self) -> dict[str, float]:
        """Which target is being published (from 0), of how many."""
        return {"target": float(self.index), "targets": float(len(self.commands))}


def commanded_joints(robot: RobotModel) -> list[str]:
    """The joints ``robot`` commands by position, in its model's order, as its
    /joint_states names them (a URDF robot's own names, without a swarm's prefix; an MJCF
    robot's in its namespace)."""
    joints = [a.joint for a in robot.actuated if a.interface == "position"]
    if robot.described:
        return [j.removeprefix(robot.prefix) for j in joints]
    return [robot.frame(j) for j in joints]
