"""A user's test of their own controller in cosim: swap it in, run three seeded worlds, assert.

Run it with ``python -m pytest examples/test_my_controller.py``. Installing cosim registers
the pytest plugin, which provides the ``cosim`` fixture and the ``cosim_seeds`` marker.

The controller below is a plain StepNode (see nodes/contract.py): it follows waypoints on
/odom, slows down when the lidar sees something close ahead, and turns to the goal's heading
at the end. It replaces the scenario's built-in ``control`` node through an override, so
scenarios/nav.yaml stays as it is. Each seed changes the lidar noise (and so what the
controller sees); the goal must be reached in every one.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from pydantic import BaseModel, ConfigDict

from nodes.contract import StepNode, Tick

NAV = Path(__file__).resolve().parents[1] / "scenarios" / "nav.yaml"

# A path around the obstacles of scenarios/nav.yaml, from (-3, -3) to (3, 3).
WAYPOINTS = [(-2.62, -2.52), (-2.47, -2.02), (-1.97, -1.62), (-1.47, -1.52), (-0.97, -1.52),
             (-0.47, -1.97), (0.03, -2.47), (0.53, -2.97), (1.03, -3.12), (1.53, -3.07),
             (2.03, -2.72), (2.43, -2.22), (2.33, -1.72), (1.88, -1.22), (1.68, -0.72),
             (1.58, -0.22), (1.98, 0.13), (2.48, 0.33), (2.98, 0.43), (3.28, 0.88),
             (3.28, 1.38), (3.18, 1.88), (3.18, 2.38), (3.03, 2.88), (3.0, 3.0)]


class FollowerParams(BaseModel):
    """What the controller is told in the scenario (checked when the scenario loads)."""

    model_config = ConfigDict(extra="forbid")
    waypoints: list[tuple[float, float]]
    goal_yaw: float = 0.0
    max_speed: float = 0.5
    max_turn: float = 1.5
    reach_distance: float = 0.2
    slow_distance: float = 0.35


class WaypointFollower(StepNode):
    """Steers towards the next waypoint; slower while misaligned or when the scan is close."""

    Params = FollowerParams

    @classmethod
    def outputs(cls, params: FollowerParams) -> dict[str, type]:
        """One velocity command per activation."""
        return {"/cmd_vel": Twist}

    def setup(self) -> None:
        """Start at the first waypoint."""
        self.index = 0

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """One command from the latest odometry (and scan, when there is one)."""
        odom: Odometry = inputs["/odom"]
        pose = odom.pose.pose
        x, y, yaw = pose.position.x, pose.position.y, _yaw(pose.orientation)
        p = self.params
        while self.index < len(p.waypoints) - 1 and self._distance(x, y) < p.reach_distance:
            self.index += 1
        cmd = Twist()
        tx, ty = p.waypoints[self.index]
        last = self.index == len(p.waypoints) - 1
        if last and self._distance(x, y) < 0.1:
            error = _wrap(p.goal_yaw - yaw)
            cmd.angular.z = _clamp(2.0 * error, p.max_turn) if abs(error) > 0.05 else 0.0
            return {"/cmd_vel": cmd}
        error = _wrap(math.atan2(ty - y, tx - x) - yaw)
        cmd.angular.z = _clamp(2.5 * error, p.max_turn)
        speed = p.max_speed * max(0.0, math.cos(error)) ** 2 * self._caution(inputs.get("/scan"))
        cmd.linear.x = min(speed, 0.8 * self._distance(x, y)) if last else speed
        return {"/cmd_vel": cmd}

    def _caution(self, scan) -> float:
        """1.0, or down to 0.5 when the lidar sees something within slow_distance ahead."""
        if scan is None:
            return 1.0
        ahead = [r for i, r in enumerate(scan.ranges)
                 if abs(_wrap(scan.angle_min + i * scan.angle_increment)) < 0.35
                 and math.isfinite(r)]
        nearest = min(ahead, default=math.inf)
        return 1.0 if nearest >= self.params.slow_distance else 0.5

    def _distance(self, x: float, y: float) -> float:
        tx, ty = self.params.waypoints[self.index]
        return math.hypot(tx - x, ty - y)


def _yaw(q) -> float:
    """Yaw of a geometry_msgs/Quaternion."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _wrap(angle: float) -> float:
    """An angle in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _clamp(value: float, limit: float) -> float:
    """value limited to [-limit, limit]."""
    return max(-limit, min(limit, value))


MY_CONTROLLER = {
    "name": "control",
    "module": f"{__name__}:WaypointFollower",  # 'package.module:Class', importable here
    "rate": 50,
    "params": {"waypoints": WAYPOINTS, "goal_yaw": 1.5708},
    "inputs": [{"topic": "/odom", "mode": "same_tick"}, {"topic": "/scan", "mode": "same_tick"}],
}


@pytest.mark.cosim_seeds(1, 2, 3)
def test_my_controller_reaches_the_goal(cosim):
    """In three seeded worlds (lidar noise), my controller gets to the goal without a hit."""
    run = cosim.run(NAV, in_process=True, overrides={"nodes.control": MY_CONTROLLER})

    assert run.success, run.summary()
    assert run.metrics["collisions"] == 0
    stamp_ns, odom = list(run.messages("/odom"))[-1]  # nav_msgs.msg.Odometry, as published
    goal = run.scenario.model.goal
    distance = math.hypot(odom.pose.pose.position.x - goal.x, odom.pose.pose.position.y - goal.y)
    assert distance <= goal.position_tolerance
    assert stamp_ns / 1e9 < 60.0
    assert all(abs(cmd.linear.x) <= 0.5 + 1e-9 for _, cmd in run.messages("/cmd_vel"))
