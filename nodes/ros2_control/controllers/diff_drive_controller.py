"""diff_drive_controller/DiffDriveController: ``~/cmd_vel`` (TwistStamped) limited as its
parameters say, stale after ``cmd_vel_timeout``, turned into the wheels' velocities (wheel
radius, separation and their multipliers), which it commands on the wheels' velocity
interfaces; ``~/odom`` from the wheels' positions over the time since its last update (its
``odometry.cpp``), its frames prefixed as upstream's (``tf_frame_prefix``, else the robot's
namespace: 'robot_2/odom'; none at the root). A command's time is its header stamp (the
tick it was published at), so the same command held by the external node is not new and
times out."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from pydantic import BaseModel, ConfigDict, Field

from nodes.ros2_control import fast_messages as fast
from nodes.ros2_control.interface import (
    NS_PER_S,
    Claim,
    ControllerInterface,
    ControllerParams,
    Update,
    seconds,
)
from nodes.ros2_control.param_types import Covariance, JointNames

CMD_VEL, ODOM = "~/cmd_vel", "~/odom"
LENGTH = "metres, more than 0 (the diff drive controller needs it: no default)"


class Limits(BaseModel):
    """One axis's limits (NaN: none), as ``linear.x`` / ``angular.z`` give them."""

    model_config = ConfigDict(extra="ignore", frozen=True)
    max_velocity: float = math.nan
    min_velocity: float = math.nan
    max_acceleration: float = math.nan
    min_acceleration: float = math.nan
    max_deceleration: float = math.nan
    max_acceleration_reverse: float = math.nan
    max_deceleration_reverse: float = math.nan
    max_jerk: float = math.nan
    min_jerk: float = math.nan


class Linear(BaseModel):
    """``linear``: the x axis's limits."""

    model_config = ConfigDict(extra="ignore", frozen=True)
    x: Limits = Limits()


class Angular(BaseModel):
    """``angular``: the z axis's limits."""

    model_config = ConfigDict(extra="ignore", frozen=True)
    z: Limits = Limits()


class DiffDriveParams(ControllerParams):
    """diff_drive_controller's parameters (its ``diff_drive_controller_parameter.yaml``;
    what cosim acts on: the rest is read and left)."""

    left_wheel_names: JointNames
    right_wheel_names: JointNames
    wheel_separation: float = Field(gt=0.0, description=LENGTH)
    wheel_radius: float = Field(gt=0.0, description=LENGTH)
    wheel_separation_multiplier: float = 1.0
    left_wheel_radius_multiplier: float = 1.0
    right_wheel_radius_multiplier: float = 1.0
    odom_frame_id: str = "odom"
    base_frame_id: str = "base_link"
    tf_frame_prefix_enable: bool = True
    tf_frame_prefix: str = Field("", description="the frames' prefix ('': the controller's "
                                 "namespace)")
    pose_covariance_diagonal: Covariance = [0.0] * 6
    twist_covariance_diagonal: Covariance = [0.0] * 6
    open_loop: bool = False
    enable_odom_tf: bool = True
    cmd_vel_timeout: float = Field(0.5, description="seconds (0: no timeout)")
    velocity_rolling_window_size: int = Field(10, gt=0, description="updates, more than 0")
    linear: Linear = Linear()
    angular: Angular = Angular()


class DiffDriveOdometry:
    """diff_drive_controller's odometry from wheel positions (its ``odometry.cpp``): the
    travel of each side, exact arc integration (second-order Runge-Kutta when straight),
    velocities as the mean over a rolling window of updates."""

    def __init__(self, separation: float, left_radius: float, right_radius: float,
                 window: int = 10):
        self.separation, self.left_radius, self.right_radius = (separation, left_radius,
                                                                right_radius)
        self.window_size = window
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
            self._window = [*self._window[-(self.window_size - 1):],
                            (linear / dt, angular / dt)]
            self.linear = sum(v for v, _ in self._window) / len(self._window)
            self.angular = sum(w for _, w in self._window) / len(self._window)


class DiffDriveController(ControllerInterface):
    """Drives a differential base's wheels from ``~/cmd_vel``; see the module."""

    Params = DiffDriveParams
    drives_base = True

    def __init__(self, name: str, params: DiffDriveParams):
        super().__init__(name, params)
        self.odometry: DiffDriveOdometry | None = None
        self.command: tuple[float, float] = (0.0, 0.0)
        self.command_ns: int | None = None
        self.last: tuple[float, float] = (0.0, 0.0)
        self.last_ns: int | None = None  # the time of the last update

    @property
    def wheels(self) -> list[str]:
        """The left wheels, then the right ones."""
        return [*self.params.left_wheel_names, *self.params.right_wheel_names]

    def claim(self) -> Claim:
        """The wheels' velocity commands and position states."""
        return Claim(tuple(f"{j}/velocity" for j in self.wheels),
                     tuple(f"{j}/position" for j in self.wheels))

    def publications(self) -> dict[str, type]:
        """``~/odom``."""
        return {ODOM: Odometry}

    def subscriptions(self) -> dict[str, type]:
        """``~/cmd_vel``."""
        return {CMD_VEL: TwistStamped}

    def notes(self) -> list[str]:
        """Jerk and reverse limits, open_loop and the odometry's transform are not
        served."""
        out = []
        for axis, limits in (("linear.x", self.params.linear.x),
                             ("angular.z", self.params.angular.z)):
            if not (math.isnan(limits.max_jerk) and math.isnan(limits.min_jerk)):
                out.append(f"{self.name}: {axis} jerk limits are not applied.")
            for key in ("max_acceleration_reverse", "max_deceleration_reverse"):
                if not math.isnan(getattr(limits, key)):
                    out.append(f"{self.name}: {axis}.{key} is not applied (the forward "
                               "limits apply both ways).")
        if self.params.open_loop:
            out.append(f"{self.name}: open_loop is not applied: the odometry integrates the "
                       "wheels' positions.")
        if self.params.enable_odom_tf:
            out.append(f"{self.name}: enable_odom_tf: the odom -> base transform on /tf comes "
                       "from the physics node (ground truth), not from this controller's "
                       "odometry, which is published on ~/odom.")
        return out

    def on_configure(self) -> None:
        """Odometry from the origin, in its frames (``frame_ids``)."""
        p = self.params
        self.frames = frame_ids(p, self.namespace)
        self.odometry = DiffDriveOdometry(
            p.wheel_separation * p.wheel_separation_multiplier,
            p.wheel_radius * p.left_wheel_radius_multiplier,
            p.wheel_radius * p.right_wheel_radius_multiplier, p.velocity_rolling_window_size)
        self.covariances = tuple(_covariance(d) for d in (p.pose_covariance_diagonal,
                                                          p.twist_covariance_diagonal))

    def on_activate(self) -> Update:
        """Odometry goes on from the wheels' positions now; the limiter starts from rest."""
        self.odometry._last = None
        self.last, self.last_ns, self.command_ns = (0.0, 0.0), None, None
        return Update()

    def on_deactivate(self) -> Update:
        """Stop the wheels."""
        self.take(0.0, 0.0, -1)
        return Update({f"{j}/velocity": 0.0 for j in self.wheels})

    def on_message(self, topic: str, msg: Any, time_ns: int) -> list[str]:
        """A new ``~/cmd_vel``, of the time its header says (now when it says none)."""
        stamp = msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec
        self.take(msg.twist.linear.x, msg.twist.angular.z, stamp or time_ns)
        return []

    def take(self, linear: float, angular: float, now_ns: int) -> None:
        """A new command (linear m/s, angular rad/s) at ``now_ns``."""
        self.command, self.command_ns = (float(linear), float(angular)), now_ns

    def update(self, time_ns: int, period_ns: int) -> Update:
        """Odometry from the wheels over the time since the last update, then the limited
        command as wheel velocities."""
        dt = seconds(period_ns if self.last_ns is None else time_ns - self.last_ns)
        self.last_ns = time_ns
        p = self.params
        left = sum(self.state[j].position for j in p.left_wheel_names) / len(p.left_wheel_names)
        right = sum(self.state[j].position for j in p.right_wheel_names) / len(
            p.right_wheel_names)
        self.odometry.update(left, right, dt)
        odom = self.odometry_message()
        left_speed, right_speed = self.wheel_speeds(time_ns, dt)
        commands = {f"{j}/velocity": left_speed for j in p.left_wheel_names}
        commands.update({f"{j}/velocity": right_speed for j in p.right_wheel_names})
        return Update(commands, {ODOM: odom})

    def wheel_speeds(self, now_ns: int, dt: float) -> tuple[float, float]:
        """The limited command as (left, right) wheel speeds in rad/s."""
        p = self.params
        v, w = self.command
        timeout = round(p.cmd_vel_timeout * NS_PER_S)
        if self.command_ns is None or (timeout > 0 and now_ns - self.command_ns > timeout):
            v, w = 0.0, 0.0
        v = limit(p.linear.x, v, self.last[0], dt)
        w = limit(p.angular.z, w, self.last[1], dt)
        self.last = (v, w)
        sep = p.wheel_separation * p.wheel_separation_multiplier
        left = (v - w * sep / 2.0) / (p.wheel_radius * p.left_wheel_radius_multiplier)
        right = (v + w * sep / 2.0) / (p.wheel_radius * p.right_wheel_radius_multiplier)
        return left, right

    def odometry_message(self) -> Odometry:
        """~/odom: the wheels' odometry in the controller's frames (built slot by slot:
        nodes.ros2_control.fast_messages)."""
        odo = self.odometry
        return fast.odometry(odo.x, odo.y, math.sin(odo.heading / 2.0),
                             math.cos(odo.heading / 2.0), odo.linear, odo.angular,
                             self.covariances[0], self.covariances[1], *self.frames)


def frame_ids(p: DiffDriveParams, namespace: str) -> tuple[str, str]:
    """~/odom's frame and child frame: ``odom_frame_id`` and ``base_frame_id`` with the TF
    prefix upstream's Jazzy controller gives them (``tf_frame_prefix_enable``, default true:
    ``tf_frame_prefix``, else the controller's namespace, followed by '/'; nothing at the
    root): 'robot_2/odom' in a swarm, 'odom' for a lone robot. A leading '/' is dropped (tf2
    refuses frame ids that start with one) and a prefix that ends in '/' gets no second."""
    prefix = (p.tf_frame_prefix or namespace) if p.tf_frame_prefix_enable else ""
    prefix = prefix.strip("/")
    prefix = f"{prefix}/" if prefix else ""
    return prefix + p.odom_frame_id, prefix + p.base_frame_id


def _covariance(diagonal) -> np.ndarray:
    """A 6x6 covariance (row-major, 36 float64) with ``diagonal`` on its diagonal."""
    out = np.zeros(36)
    for i, value in enumerate(diagonal):
        out[7 * i] = value
    return out


def limit(limits: Limits, value: float, last: float, dt: float) -> float:
    """ros2_controllers' speed limiter: velocity, then acceleration (NaN: no limit;
    ``min_acceleration``, as upstream's, the lower bound of the change per second)."""
    high, low = limits.max_velocity, limits.min_velocity
    if not math.isnan(high):
        low = -high if math.isnan(low) else low
        value = min(max(value, low), high)
    if dt > 0:
        speeding_up = abs(value) > abs(last)
        step = limits.max_acceleration if speeding_up else limits.max_deceleration
        if math.isnan(step):
            step = limits.max_acceleration
        if not math.isnan(step) and step > 0:
            value = min(max(value, last - step * dt), last + step * dt)
        if not math.isnan(limits.min_acceleration):
            value = max(value, last + limits.min_acceleration * dt)
    return value
