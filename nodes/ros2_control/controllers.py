"""The standard controllers of ros2_controllers as pure objects: each is told the hardware's
joint state and its own inputs at every update of the controller manager, and says what it
commands (joint positions, a base twist) and what it publishes.

Behaviour follows the Jazzy documentation and sources of ros2_controllers, with the
differences docs/concepts/topics.md (ros2_control) lists (cosim's joints take position
commands; a diff drive's wheels are driven through the physics node's drive).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from nodes.ros2_control.config import ControllerSpec
from nodes.ros2_control.trajectory import NS_PER_S, Point, Sample, Trajectory

# control_msgs/action/FollowJointTrajectory result codes
SUCCESSFUL, INVALID_GOAL, INVALID_JOINTS = 0, -1, -2
OLD_HEADER_TIMESTAMP, PATH_TOLERANCE_VIOLATED, GOAL_TOLERANCE_VIOLATED = -3, -4, -5
# the state of the trajectory controller's newest action goal (its metric ``goal_state``)
IDLE, ACTIVE, SUCCEEDED, ABORTED, CANCELED = 0, 1, 2, 3, 4


@dataclass
class JointReading:
    """One joint of the hardware's state: position, velocity, effort."""

    position: float
    velocity: float = 0.0
    effort: float = 0.0


HardwareState = dict[str, JointReading]


class ForwardCommand:
    """forward_command_controller and the joint group position/velocity controllers: the
    latest ``~/commands`` (std_msgs/Float64MultiArray, one value per joint in order) goes to
    the joints; a message of another length is refused (a note) and the last one kept."""

    def __init__(self, spec: ControllerSpec):
        self.spec = spec
        self.command: list[float] | None = None

    def take(self, values: list[float]) -> str | None:
        """Take a command; the reason it is refused, or None."""
        if len(values) != len(self.spec.joints):
            return (f"{self.spec.name}/commands refused: {len(values)} values for "
                    f"{len(self.spec.joints)} joints {list(self.spec.joints)}")
        if not all(math.isfinite(v) for v in values):
            return f"{self.spec.name}/commands refused: a value is not finite"
        self.command = [float(v) for v in values]
        return None

    def positions(self) -> dict[str, float]:
        """Joint -> commanded position (nothing before the first command)."""
        if self.command is None:
            return {}
        return dict(zip(self.spec.joints, self.command, strict=True))


@dataclass
class GoalTolerances:
    """Per-joint path and goal tolerances of the active trajectory, and the goal time."""

    path_position: list[float]
    path_velocity: list[float]
    goal_position: list[float]
    goal_velocity: list[float]
    goal_time_ns: int


class TrajectoryController:
    """joint_trajectory_controller: follows the newest trajectory, from the ``~/joint_trajectory``
    topic or a FollowJointTrajectory goal, sampled at every update (nodes.ros2_control.trajectory);
    checks path tolerances while it moves and goal tolerances at its end; holds where it is
    when there is nothing to follow, when a goal is cancelled or aborted."""

    def __init__(self, spec: ControllerSpec):
        self.spec = spec
        self.joints = list(spec.joints)
        self.trajectory: Trajectory | None = None
        self.hold: list[float] | None = None
        self.desired: Sample | None = None
        self.goal_seq = 0
        self.goal_state = IDLE
        self.error_code = SUCCESSFUL
        self.error_joint = -1
        self.tolerances: GoalTolerances | None = None
        self.from_action = False

    def defaults(self) -> GoalTolerances:
        """The tolerances of the controller's parameters (constraints)."""
        tol = [self.spec.tolerances[j] for j in self.joints]
        goal_time = round(self.spec.params["goal_time"] * NS_PER_S)
        stopped = self.spec.params["stopped_velocity_tolerance"]
        return GoalTolerances([t.trajectory for t in tol], [0.0] * len(tol),
                              [t.goal for t in tol], [stopped] * len(tol), goal_time)

    def activate(self, state: HardwareState) -> None:
        """Hold the joints where they are."""
        self.hold = [state[j].position for j in self.joints]
        self.trajectory = None

    def _check(self, msg) -> tuple[int, str] | None:
        """Why a trajectory message is not taken, as (result code, text), or None."""
        names = list(msg.joint_names)
        unknown = [n for n in names if n not in self.joints]
        if unknown:
            return INVALID_JOINTS, (f"joint {unknown[0]!r} is not a joint of {self.spec.name} "
                                    f"({', '.join(self.joints)})")
        if len(set(names)) != len(names):
            return INVALID_JOINTS, "a joint is named twice"
        if set(names) != set(self.joints) and not self.spec.params["allow_partial_joints_goal"]:
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
        if msg.points and not self.spec.params["allow_nonzero_velocity_at_trajectory_end"]:
            end = msg.points[-1].velocities
            if any(v != 0.0 for v in end):
                return INVALID_GOAL, ("the last point has a nonzero velocity and "
                                      "allow_nonzero_velocity_at_trajectory_end is false")
        return None

    def take(self, msg, now_ns: int, state: HardwareState, tolerances: GoalTolerances | None
             = None) -> tuple[int, str] | None:
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

    def update(self, now_ns: int, state: HardwareState) -> None:
        """Sample the trajectory, check tolerances, end the goal when it is done."""
        if self.trajectory is None:
            hold = self.hold or [state[j].position for j in self.joints]
            self.desired = Sample(list(hold), [0.0] * len(hold), [0.0] * len(hold), True)
            return
        sample = self.trajectory.sample(now_ns, self.spec.params["interpolate"])
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
        if self.from_action and self.goal_state == ACTIVE:
            self.goal_state, self.error_code, self.error_joint = outcome, code, joint
        if keep:  # the trajectory ends where its last point is: hold that
            self.hold = list(self.trajectory.points[-1].positions)
            self.trajectory = None
        else:
            self.stop(state)
        self.from_action = False

    def positions(self) -> dict[str, float]:
        """Joint -> commanded position."""
        if self.desired is None:
            return {}
        return dict(zip(self.joints, self.desired.positions, strict=True))


def _outside(tolerance: float, error: float) -> bool:
    """Whether ``error`` breaks ``tolerance`` (0: not checked; negative: never broken)."""
    return tolerance > 0.0 and abs(error) > tolerance


class DiffDriveOdometry:
    """diff_drive_controller's odometry from wheel positions (its ``odometry.cpp``): the
    travel of each side, exact arc integration (second-order Runge-Kutta when straight),
    velocities as the mean over a rolling window of updates."""

    WINDOW = 10

    def __init__(self, separation: float, left_radius: float, right_radius: float):
        self.separation, self.left_radius, self.right_radius = (separation, left_radius,
                                                                right_radius)
        self.x = self.y = self.heading = 0.0
        self.linear = self.angular = 0.0
        self._last: tuple[float, float] | None = None
        self._window: list[tuple[float, float]] = []

    def update(self, left_pos: float, right_pos: float, dt: float) -> None:
        """Integrate from the wheels' positions (rad) after ``dt`` seconds."""
        left, right = left_pos * self.left_radius, right_pos * self.right_radius
        if self._last is None:
            self._last = (left, right)
            return
        d_left, d_right = left - self._last[0], right - self._last[1]
        self._last = (left, right)
        linear = (d_left + d_right) * 0.5
        angular = (d_right - d_left) / self.separation
        if abs(angular) < 1e-6:
            direction = self.heading + angular * 0.5
            self.x += linear * math.cos(direction)
            self.y += linear * math.sin(direction)
            self.heading += angular
        else:
            old = self.heading
            radius = linear / angular
            self.heading += angular
            self.x += radius * (math.sin(self.heading) - math.sin(old))
            self.y += -radius * (math.cos(self.heading) - math.cos(old))
        if dt > 0:
            self._window = [*self._window[-(self.WINDOW - 1):], (linear / dt, angular / dt)]
            self.linear = sum(v for v, _ in self._window) / len(self._window)
            self.angular = sum(w for _, w in self._window) / len(self._window)


class DiffDrive:
    """diff_drive_controller: ``~/cmd_vel`` (TwistStamped) limited as its parameters say, stale
    after ``cmd_vel_timeout``; the wheel speeds it gives (wheel radius, separation and their
    multipliers) are what the base is driven at; ``~/odom`` from the wheels' positions."""

    def __init__(self, spec: ControllerSpec, physics: tuple[float, float]):
        self.spec = spec
        self.physics = physics  # (wheel radius, separation) of the physics node's drive
        p = spec.params
        self.odometry = DiffDriveOdometry(p["wheel_separation"] * p["wheel_separation_multiplier"],
                                          p["wheel_radius"] * p["left_wheel_radius_multiplier"],
                                          p["wheel_radius"] * p["right_wheel_radius_multiplier"])
        self.command: tuple[float, float] = (0.0, 0.0)
        self.command_ns: int | None = None
        self.last: tuple[float, float] = (0.0, 0.0)

    def take(self, linear: float, angular: float, now_ns: int) -> None:
        """A new ``~/cmd_vel``."""
        self.command, self.command_ns = (float(linear), float(angular)), now_ns

    def wheel_speeds(self, now_ns: int, dt: float) -> tuple[float, float]:
        """The limited command as (left, right) wheel speeds in rad/s."""
        p = self.spec.params
        v, w = self.command
        timeout = round(p["cmd_vel_timeout"] * NS_PER_S)
        if self.command_ns is None or (timeout > 0 and now_ns - self.command_ns > timeout):
            v, w = 0.0, 0.0
        v = _limit(p, "linear.x", v, self.last[0], dt)
        w = _limit(p, "angular.z", w, self.last[1], dt)
        self.last = (v, w)
        sep = p["wheel_separation"] * p["wheel_separation_multiplier"]
        left = (v - w * sep / 2.0) / (p["wheel_radius"] * p["left_wheel_radius_multiplier"])
        right = (v + w * sep / 2.0) / (p["wheel_radius"] * p["right_wheel_radius_multiplier"])
        return left, right

    def update_odometry(self, state: HardwareState, dt: float) -> None:
        """Odometry from the mean position of each side's wheels."""
        p = self.spec.params
        left = sum(state[j].position for j in p["left"]) / len(p["left"])
        right = sum(state[j].position for j in p["right"]) / len(p["right"])
        self.odometry.update(left, right, dt)


def _limit(p: dict, axis: str, value: float, last: float, dt: float) -> float:
    """ros2_controllers' speed limiter: velocity, then acceleration (NaN: no limit)."""
    high, low = p[f"{axis}.max_velocity"], p[f"{axis}.min_velocity"]
    if not math.isnan(high):
        low = -high if math.isnan(low) else low
        value = min(max(value, low), high)
    if dt > 0:
        speeding_up = abs(value) > abs(last)
        step = p[f"{axis}.max_acceleration"] if speeding_up else p[f"{axis}.max_deceleration"]
        if math.isnan(step):
            step = p[f"{axis}.max_acceleration"]
        if not math.isnan(step) and step > 0:
            value = min(max(value, last - step * dt), last + step * dt)
    return value
