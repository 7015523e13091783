"""joint_trajectory_controller/JointTrajectoryController: follows the newest trajectory,
from ``~/joint_trajectory`` or a FollowJointTrajectory goal, sampled at every update as
upstream samples it (nodes.ros2_control.trajectory); checks path tolerances while it moves
and goal tolerances at its end; holds where it is when there is nothing to follow, when a
goal is cancelled or aborted. Publishes ``~/controller_state``.

The ``~/follow_joint_trajectory`` action is served by the orchestrator (the manager's face),
whose goals and cancels enter here at a tick boundary on ``~/cosim/goal``
(control_msgs/action/FollowJointTrajectory_Goal, named in the trajectory's frame_id:
``nodes.ros2_control.goals``, the protocol the gripper shares); the goal's state reaches the
face as this controller's metrics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTrajectoryControllerState
from pydantic import BaseModel, ConfigDict, Field, model_validator
from trajectory_msgs.msg import JointTrajectory

from nodes.ros2_control import fast_messages as fast
from nodes.ros2_control.goals import (  # noqa: F401  (re-exported: the face's names)
    ABORTED,
    ACTIVE,
    CANCEL_ID,
    CANCELED,
    GOAL_ID,
    IDLE,
    INVALID_GOAL,
    SUCCEEDED,
    SUCCESSFUL,
    GoalProtocol,
)
from nodes.ros2_control.interface import (
    Claim,
    ControllerInterface,
    ControllerParams,
    HardwareState,
    Update,
)
from nodes.ros2_control.param_types import JointNames
from nodes.ros2_control.trajectory import NS_PER_S, Point, Sample, Trajectory

# control_msgs/action/FollowJointTrajectory result codes (SUCCESSFUL, INVALID_GOAL: goals)
INVALID_JOINTS = -2
OLD_HEADER_TIMESTAMP, PATH_TOLERANCE_VIOLATED, GOAL_TOLERANCE_VIOLATED = -3, -4, -5
TRAJECTORY, GOAL, STATE = "~/joint_trajectory", "~/cosim/goal", "~/controller_state"
FOLLOW = "~/follow_joint_trajectory"


class JointTolerance(BaseModel):
    """A joint's tolerances (0: not checked), as ``constraints.<joint>`` gives them."""

    model_config = ConfigDict(extra="ignore", frozen=True)
    trajectory: float = Field(0.0, description="the path tolerance of the position, rad or m")
    goal: float = Field(0.0, description="the goal tolerance of the position, rad or m")


class Constraints(BaseModel):
    """``constraints``: the stopped velocity, the goal time and per-joint tolerances."""

    model_config = ConfigDict(extra="allow", frozen=True)
    stopped_velocity_tolerance: float = Field(0.01, description="the velocity under which a "
                                              "joint is stopped at the goal, rad/s or m/s")
    goal_time: float = Field(0.0, ge=0.0, description="seconds, 0 or more (0: wait as long "
                             "as it takes)")
    decelerate_on_cancel: bool = False

    def joint(self, name: str) -> JointTolerance:
        """The tolerances of joint ``name``."""
        return JointTolerance.model_validate((self.model_extra or {}).get(name) or {})


class JointTrajectoryParams(ControllerParams):
    """joint_trajectory_controller's parameters (its ``joint_trajectory_controller.yaml``;
    what cosim acts on: the rest is read and left)."""

    joints: JointNames
    command_interfaces: list[Literal["position"]] = Field(
        min_length=1, max_length=1, description="[position]: cosim's trajectory controller "
        "commands positions")
    state_interfaces: list[Literal["position", "velocity", "acceleration"]] = Field(
        ["position", "velocity"], description="a subset of [position, velocity, acceleration]")
    allow_partial_joints_goal: bool = False
    allow_nonzero_velocity_at_trajectory_end: bool = False
    interpolation_method: Literal["splines", "none"] = Field(
        "splines", description="splines or none")
    constraints: Constraints = Field(Constraints(), description=(
        "{stopped_velocity_tolerance: 0.01, goal_time: 0.0, <joint>: {trajectory: 0.1, "
        "goal: 0.05}}"))
    gains: dict[str, Any] = {}

    @model_validator(mode="after")
    def _constraints_name_joints(self):
        unknown = sorted(set(self.constraints.model_extra or {}) - set(self.joints))
        if unknown:
            raise ValueError(f"constraints.{unknown[0]} is not a joint of this controller "
                             f"(its joints: {', '.join(self.joints)})")
        for joint in self.joints:
            self.constraints.joint(joint)  # a wrong tolerance says so here
        return self


@dataclass
class GoalTolerances:
    """Per-joint path and goal tolerances of the active trajectory, and the goal time."""

    path_position: list[float]
    path_velocity: list[float]
    goal_position: list[float]
    goal_velocity: list[float]
    goal_time_ns: int


class JointTrajectoryController(ControllerInterface):
    """Follows trajectories from its topic and its action; see the module."""

    Params = JointTrajectoryParams

    def __init__(self, name: str, params: JointTrajectoryParams):
        super().__init__(name, params)
        self.joints = list(params.joints)
        self.trajectory: Trajectory | None = None
        self.hold: list[float] | None = None
        self.desired: Sample | None = None
        self.goal = GoalProtocol()
        self.error_joint = -1
        self.tolerances: GoalTolerances | None = None
        self.from_action = False

    # -- what it declares ------------------------------------------------------------------

    def claim(self) -> Claim:
        """Its joints' command and state interfaces."""
        p = self.params
        return Claim(tuple(f"{j}/{i}" for j in p.joints for i in p.command_interfaces),
                     tuple(f"{j}/{i}" for j in p.joints for i in p.state_interfaces))

    def publications(self) -> dict[str, type]:
        """``~/controller_state``."""
        return {STATE: JointTrajectoryControllerState}

    def empty_message(self, topic: str) -> JointTrajectoryControllerState:
        """An empty ~/controller_state (as the message's constructor makes it), built slot
        by slot: it is published at every tick the controller is inactive."""
        return fast.controller_state([], fast.point(), fast.point(), fast.point(),
                                     fast.point(), speed_scaling_factor=0.0)

    def subscriptions(self) -> dict[str, type]:
        """``~/joint_trajectory`` and the action's goals and cancels."""
        return {TRAJECTORY: JointTrajectory, GOAL: FollowJointTrajectory.Goal}

    def actions(self) -> dict[str, type]:
        """``~/follow_joint_trajectory``."""
        return {FOLLOW: FollowJointTrajectory}

    def notes(self) -> list[str]:
        """PID gains are read and not used."""
        if self.params.gains:
            return [f"{self.name}: gains are not used: cosim's joints take position commands "
                    "(the PID gains of ros2_control apply to velocity or effort interfaces)."]
        return []

    def metrics(self) -> dict[str, float]:
        """The newest action goal: its number, state, result code, whether a deactivation
        ended it, the joint that broke a tolerance."""
        return {**self.goal.metrics(), "error_joint": float(self.error_joint)}

    # -- the lifecycle ---------------------------------------------------------------------

    def on_activate(self) -> Update:
        """Hold the joints where they are."""
        self.hold = [self.state[j].position for j in self.joints]
        self.trajectory = None
        return Update()

    def on_deactivate(self) -> Update:
        """Hold where the joints are (the hardware keeps that command); an executing goal is
        aborted, as upstream's."""
        self.stop(self.state)
        if self.goal.deactivate():
            self.from_action = False
        return Update()

    def defaults(self) -> GoalTolerances:
        """The tolerances of the controller's parameters (constraints)."""
        c = self.params.constraints
        tol = [c.joint(j) for j in self.joints]
        stopped = c.stopped_velocity_tolerance
        return GoalTolerances([t.trajectory for t in tol], [0.0] * len(tol),
                              [t.goal for t in tol], [stopped] * len(tol),
                              round(c.goal_time * NS_PER_S))

    # -- its inputs ------------------------------------------------------------------------

    def on_message(self, topic: str, msg: Any, time_ns: int) -> list[str]:
        """A trajectory on its topic (a new one preempts an action goal) or a goal or cancel
        of its action."""
        if topic == TRAJECTORY:
            return self._topic_trajectory(msg, time_ns)
        return self._goal(msg, time_ns)

    def _topic_trajectory(self, msg: JointTrajectory, now: int) -> list[str]:
        if _blank(msg):
            return []
        if self.goal.end(CANCELED):  # a topic message preempts an action goal
            self.from_action = False
        if why := self.take(msg, now, self.state):
            return [f"{self.name}/joint_trajectory refused: {why[1]}"]
        return []

    def _goal(self, goal, now: int) -> list[str]:
        name = goal.trajectory.header.frame_id
        # the orchestrator names each goal and cancel in the trajectory's frame_id
        kind = GoalProtocol.kind(name)
        if kind is None:
            return []
        if kind == "cancel":
            if self.goal.end(CANCELED):
                self.stop(self.state)
                self.from_action = False
            return []
        self.goal.begin(name)
        self.error_joint = -1
        why = self.take(goal.trajectory, now, self.state, goal_tolerances(self, goal))
        if why:
            self.goal.end(ABORTED, why[0])
            return [f"{self.name}/follow_joint_trajectory goal {self.goal.goal_id} refused: "
                    f"{why[1]}"]
        self.from_action = True
        if not goal.trajectory.points:
            self.goal.end(SUCCEEDED)
        return []

    def _check(self, msg) -> tuple[int, str] | None:
        """Why a trajectory message is not taken, as (result code, text), or None."""
        names = list(msg.joint_names)
        unknown = [n for n in names if n not in self.joints]
        if unknown:
            return INVALID_JOINTS, (f"joint {unknown[0]!r} is not a joint of {self.name} "
                                    f"({', '.join(self.joints)})")
        if len(set(names)) != len(names):
            return INVALID_JOINTS, "a joint is named twice"
        if set(names) != set(self.joints) and not self.params.allow_partial_joints_goal:
            missing = [j for j in self.joints if j not in names]
            return INVALID_JOINTS, (f"joints {missing} are missing and "
                                    "allow_partial_joints_goal is false")
        last_ns = -1
        for i, point in enumerate(msg.points):
            t = point.time_from_start.sec * NS_PER_S + point.time_from_start.nanosec
            if t <= last_ns and i > 0:
                return INVALID_GOAL, (f"point {i}: time_from_start does not increase")
            last_ns = t
            if len(point.positions) != len(names):
                return INVALID_GOAL, (f"point {i} has {len(point.positions)} positions for "
                                      f"{len(names)} joints")
            for field_name in ("velocities", "accelerations"):
                values = getattr(point, field_name)
                if len(values) not in (0, len(names)):
                    return INVALID_GOAL, (f"point {i} has {len(values)} {field_name} for "
                                          f"{len(names)} joints")
        if msg.points and not self.params.allow_nonzero_velocity_at_trajectory_end:
            end = msg.points[-1].velocities
            if any(v != 0.0 for v in end):
                return INVALID_GOAL, ("the last point has a nonzero velocity and "
                                      "allow_nonzero_velocity_at_trajectory_end is false")
        return None

    def take(self, msg, now_ns: int, state: HardwareState,
             tolerances: GoalTolerances | None = None) -> tuple[int, str] | None:
        """Follow trajectory ``msg`` from now (an empty one stops: hold where the joints are).
        Returns why it was refused, or None."""
        problem = self._check(msg)
        if problem:
            return problem
        if not msg.points:
            self.stop(state)
            return None
        order = [list(msg.joint_names).index(j) if j in msg.joint_names else -1
                 for j in self.joints]
        current = self.desired.positions if self.desired else (
            self.hold or [state[j].position for j in self.joints])

        def full(values, fallback):
            if not values:
                return []
            return [values[k] if k >= 0 else fallback[i] for i, k in enumerate(order)]

        points = [Point(p.time_from_start.sec * NS_PER_S + p.time_from_start.nanosec,
                        full(list(p.positions), current),
                        full(list(p.velocities), [0.0] * len(self.joints)),
                        full(list(p.accelerations), [0.0] * len(self.joints)))
                  for p in msg.points]
        stamp = msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec
        start = stamp if stamp > 0 else now_ns
        if start + points[-1].time_ns < now_ns:
            return OLD_HEADER_TIMESTAMP, "the trajectory ends before now"
        before = Point(0, [state[j].position for j in self.joints],
                       [state[j].velocity for j in self.joints], [0.0] * len(self.joints))
        self.trajectory = Trajectory(points, start, before, now_ns)
        self.tolerances = tolerances or self.defaults()
        return None

    def stop(self, state: HardwareState) -> None:
        """Hold the joints where they are now."""
        self.trajectory = None
        self.hold = [state[j].position for j in self.joints]
        self.desired = None

    # -- the update ------------------------------------------------------------------------

    def update(self, time_ns: int, period_ns: int) -> Update:
        """Sample the trajectory, check tolerances, end the goal when it is done; command the
        desired positions and publish ``~/controller_state``."""
        self._follow(time_ns, self.state)
        commands = {}
        if self.desired is not None:
            commands = {f"{j}/position": p for j, p in
                        zip(self.joints, self.desired.positions, strict=True)}
        return Update(commands, {STATE: controller_state(self, self.state)})

    def _follow(self, now_ns: int, state: HardwareState) -> None:
        if self.trajectory is None:
            hold = self.hold or [state[j].position for j in self.joints]
            self.desired = Sample(list(hold), [0.0] * len(hold), [0.0] * len(hold), True)
            return
        sample = self.trajectory.sample(now_ns, self.params.interpolation_method == "splines")
        self.desired = sample
        tol = self.tolerances
        actual = [state[j] for j in self.joints]
        if not sample.past_end:
            for i, reading in enumerate(actual):
                if _outside(tol.path_position[i], sample.positions[i] - reading.position) or \
                        _outside(tol.path_velocity[i], sample.velocities[i] - reading.velocity):
                    self._end(ABORTED, PATH_TOLERANCE_VIOLATED, i, state)
                    return
            return
        within = all(
            not _outside(tol.goal_position[i], sample.positions[i] - r.position)
            and not _outside(tol.goal_velocity[i], r.velocity)
            for i, r in enumerate(actual))
        if within:
            self._end(SUCCEEDED, SUCCESSFUL, -1, state, keep=True)
        elif tol.goal_time_ns > 0 and now_ns > self.trajectory.end_ns + tol.goal_time_ns:
            worst = max(range(len(actual)), key=lambda i: abs(sample.positions[i]
                                                               - actual[i].position))
            self._end(ABORTED, GOAL_TOLERANCE_VIOLATED, worst, state)

    def _end(self, outcome: int, code: int, joint: int, state: HardwareState,
             keep: bool = False) -> None:
        if self.from_action and self.goal.end(outcome, code):
            self.error_joint = joint
        if keep:  # the trajectory ends where its last point is: hold that
            self.hold = list(self.trajectory.points[-1].positions)
            self.trajectory = None
        else:
            self.stop(state)
        self.from_action = False


def _outside(tolerance: float, error: float) -> bool:
    """Whether ``error`` breaks ``tolerance`` (0: not checked; negative: never broken)."""
    return tolerance > 0.0 and abs(error) > tolerance


def _blank(msg: JointTrajectory) -> bool:
    """Whether ``msg`` is the external node's stand-in until a client sends a trajectory (a
    default-constructed one: no joints, no points): nothing was sent, so nothing is refused."""
    return not msg.joint_names and not msg.points and not msg.header.frame_id


def goal_tolerances(ctrl: JointTrajectoryController, goal) -> GoalTolerances:
    """The goal's tolerances over the controller's defaults: a value 0 keeps the default,
    -1 means no tolerance (control_msgs/JointTolerance)."""
    tol = ctrl.defaults()
    index = {j: i for i, j in enumerate(ctrl.joints)}
    for entries, pos, vel in ((goal.path_tolerance, tol.path_position, tol.path_velocity),
                              (goal.goal_tolerance, tol.goal_position, tol.goal_velocity)):
        for entry in entries:
            i = index.get(entry.name)
            if i is None:
                continue
            if entry.position != 0.0:
                pos[i] = entry.position
            if entry.velocity != 0.0:
                vel[i] = entry.velocity
    t = goal.goal_time_tolerance
    if t.sec or t.nanosec:
        tol.goal_time_ns = t.sec * NS_PER_S + t.nanosec
    return tol


def controller_state(ctrl: JointTrajectoryController, state: HardwareState
                     ) -> JointTrajectoryControllerState:
    """~/controller_state: reference, feedback, error and output of every joint."""
    joints = ctrl.joints
    positions = [state[j].position for j in joints]
    velocities = [state[j].velocity for j in joints]
    feedback = fast.point(positions, velocities)
    desired = ctrl.desired
    if desired is None:
        reference, error, output = fast.point(), fast.point(), fast.point()
    else:
        reference = fast.point(desired.positions, desired.velocities, desired.accelerations)
        error = fast.point([d - f for d, f in zip(desired.positions, positions, strict=True)],
                           [d - f for d, f in zip(desired.velocities, velocities,
                                                  strict=True)])
        output = fast.point(desired.positions)
    return fast.controller_state(joints, reference, feedback, error, output)
