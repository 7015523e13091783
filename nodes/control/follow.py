"""Local planning: regulated pure pursuit along the global plan, checked against the scan.

The robot is a circle of ``robot_radius``. A candidate arc (v, w) is rolled out ahead and
its first pose closer than radius + margin to a scan point bounds the allowed speed, so the
robot slows and stops short of anything the map did not know about.
"""

from __future__ import annotations

import math

import numpy as np


def wrap(a: float) -> float:
    """An angle wrapped to [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def scan_points(ranges: np.ndarray, angle_min: float, inc: float, range_min: float,
                laser: tuple[float, float, float], pose: tuple[float, float, float]
                ) -> np.ndarray:
    """Valid scan returns as (n, 2) points in the odom frame.

    ``laser`` is the laser's (x, y, yaw) on the base, ``pose`` the base's in odom.
    """
    angles = angle_min + inc * np.arange(len(ranges))
    ok = np.isfinite(ranges) & (ranges >= range_min)
    r, a = ranges[ok], angles[ok] + laser[2]
    bx = laser[0] + r * np.cos(a)
    by = laser[1] + r * np.sin(a)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.stack([pose[0] + c * bx - s * by, pose[1] + s * bx + c * by], axis=1)


def arc_clearance(points: np.ndarray, pose: tuple[float, float, float], v: float, w: float,
                  horizon: float, radius: float) -> float:
    """Distance (m) the robot can drive along arc (v, w) before a point is within ``radius``.

    Returns ``horizon`` when the arc is clear for that distance. Works for v < 0 (backing up).
    """
    if len(points) == 0 or v == 0:
        return horizon
    ds = 0.05
    s = np.arange(ds, horizon + 1e-9, ds)
    k = w / abs(v)
    th = pose[2] + k * s
    sign = math.copysign(1.0, v)
    if abs(k) < 1e-6:
        xs = pose[0] + sign * s * math.cos(pose[2])
        ys = pose[1] + sign * s * math.sin(pose[2])
    else:
        xs = pose[0] + sign * (np.sin(th) - math.sin(pose[2])) / k
        ys = pose[1] - sign * (np.cos(th) - math.cos(pose[2])) / k
    near = points[np.hypot(points[:, 0] - pose[0], points[:, 1] - pose[1]) < horizon + radius]
    if len(near) == 0:
        return horizon
    d2 = (xs[:, None] - near[None, :, 0]) ** 2 + (ys[:, None] - near[None, :, 1]) ** 2
    hit = np.flatnonzero(d2.min(axis=1) < radius * radius)
    return float(s[hit[0]] - ds) if hit.size else horizon


def arc_end(pose: tuple[float, float, float], k: float, s: float) -> tuple[float, float]:
    """Where driving ``s`` metres forward on curvature ``k`` from ``pose`` ends."""
    x, y, th = pose
    if abs(k) < 1e-6:
        return x + s * math.cos(th), y + s * math.sin(th)
    return (x + (math.sin(th + k * s) - math.sin(th)) / k,
            y - (math.cos(th + k * s) - math.cos(th)) / k)


def escape_arc(points: np.ndarray, pose: tuple[float, float, float], target: np.ndarray,
               speed: float, radius: float, reach: float, max_curvature: float
               ) -> float | None:
    """The curvature of the forward arc, clear of the scan by ``radius`` for ``reach`` metres,
    that ends closest to ``target``; None when every arc is blocked."""
    best, best_gap = None, math.inf
    for k in np.linspace(-max_curvature, max_curvature, 17).tolist():
        if arc_clearance(points, pose, speed, speed * k, reach, radius) < reach:
            continue
        x, y = arc_end(pose, k, reach)
        gap = math.hypot(target[0] - x, target[1] - y)
        if gap < best_gap:
            best, best_gap = k, gap
    return best


def lookahead_point(path: np.ndarray, index: int, pose: tuple[float, float, float],
                    lookahead: float, window: int = 40) -> tuple[int, np.ndarray]:
    """(closest index, point ``lookahead`` ahead of it) on a (n, 2) path; never goes back."""
    seg = path[index:index + window]
    d = np.hypot(seg[:, 0] - pose[0], seg[:, 1] - pose[1])
    index += int(np.argmin(d))
    ahead = np.hypot(path[index:, 0] - pose[0], path[index:, 1] - pose[1])
    far = np.flatnonzero(ahead >= lookahead)
    return index, path[index + int(far[0])] if far.size else path[-1]
