"""Poses in the plane: the heading of a quaternion and the (x, y, yaw) of a pose, one formula
for every reader (the control node, the NavigateToPose server, the report, the world checks)."""

from __future__ import annotations

import math
from typing import Any


def yaw(w: float, x: float, y: float, z: float) -> float:
    """Heading (rotation about z) of the quaternion (w, x, y, z)."""
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def yaw_of(q: Any) -> float:
    """Heading of a geometry_msgs Quaternion."""
    return yaw(q.w, q.x, q.y, q.z)


def pose_of(pose: Any) -> tuple[float, float, float]:
    """(x, y, yaw) of a geometry_msgs Pose."""
    return float(pose.position.x), float(pose.position.y), yaw_of(pose.orientation)
