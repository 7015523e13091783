"""The node of docs/tutorials/own-node.md: how far the robot is from a point, on /distance.

A cosim node is a pure step function: it reads its inputs (ROS 2 messages keyed by topic),
returns its outputs, and never touches a clock or a transport. Run it in
examples/distance.yaml:

    cosim-orchestrate examples/distance.yaml --in-process
"""

from __future__ import annotations

import math
from typing import Any

from nav_msgs.msg import Odometry
from pydantic import BaseModel, ConfigDict, Field
from std_msgs.msg import Float64

from nodes.contract import StepNode, Tick


class DistanceParams(BaseModel):
    """The point to measure from (checked when the scenario loads: unknown keys refused)."""

    model_config = ConfigDict(extra="forbid")
    x: float = Field(0.0, description="m")
    y: float = Field(0.0, description="m")


class DistanceNode(StepNode):
    """Publishes the robot's distance to (x, y) from each /odom it is given."""

    Params = DistanceParams

    @classmethod
    def outputs(cls, params: DistanceParams) -> dict[str, type]:
        """One Float64 on /distance per activation."""
        return {"/distance": Float64}

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """The distance from this tick's odometry; a note once it is under a metre."""
        odom: Odometry = inputs["/odom"]
        where = odom.pose.pose.position
        distance = math.hypot(where.x - self.params.x, where.y - self.params.y)
        if distance < 1.0 and not getattr(self, "_close", False):
            self._close = True
            self.note(f"within 1 m of ({self.params.x}, {self.params.y})")
        return {"/distance": Float64(data=distance)}
