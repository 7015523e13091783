"""Local planning: regulated pure pursuit along the global plan, checked against the scan.

The robot is a circle of ``robot_radius``. A candidate arc (v, w) is rolled out ahead and
its first pose closer than radius + margin to a scan point bounds the allowed speed, so the
robot slows and stops short of anything the map did not know about.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

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


ARC_STEP = 0.05  # m between the poses of an arc checked against the scan
_ARC_SAMPLES: dict[float, np.ndarray] = {}  # horizon -> arc lengths of the poses checked


def _arc_samples(horizon: float) -> np.ndarray:
    s = _ARC_SAMPLES.get(horizon)
    if s is None:
        if len(_ARC_SAMPLES) > 64:
            _ARC_SAMPLES.clear()
        s = _ARC_SAMPLES[horizon] = np.arange(ARC_STEP, horizon + 1e-9, ARC_STEP)
        s.flags.writeable = False
    return s


def arc_clearance(points: np.ndarray, pose: tuple[float, float, float], v: float, w: float,
                  horizon: float, radius: float) -> float:
    """Distance (m) the robot can drive along arc (v, w) before a point is within ``radius``.

    Returns ``horizon`` when the arc is clear for that distance. Works for v < 0 (backing up).
    """
    return arc_clearances(points, pose, v, (w,), horizon, radius)[0]


def arc_clearances(points: np.ndarray, pose: tuple[float, float, float], v: float,
                   ws: Sequence[float], horizon: float, radius: float) -> list[float]:
    """``arc_clearance`` of every arc (v, w) for w in ``ws``, at once: the scan points near
    the robot picked once, every arc's poses and their distances to them in one array.

    Each pose and each squared distance is the same IEEE operations on the same operands
    as one arc alone (elementwise, no reduction but the exact minimum), so each result is
    the one arc's bit for bit.
    """
    if len(points) == 0 or v == 0 or not ws:
        return [horizon] * len(ws)
    near = points[np.hypot(points[:, 0] - pose[0], points[:, 1] - pose[1]) < horizon + radius]
    if len(near) == 0:
        return [horizon] * len(ws)
    s = _arc_samples(horizon)
    sign = math.copysign(1.0, v)
    ks = [w / abs(v) for w in ws]
    straight = [abs(k) < 1e-6 for k in ks]
    xs = np.empty((len(ks), len(s)))
    ys = np.empty((len(ks), len(s)))
    if any(straight):
        rows = np.array(straight)
        xs[rows] = pose[0] + sign * s * math.cos(pose[2])
        ys[rows] = pose[1] + sign * s * math.sin(pose[2])
    if not all(straight):
        rows = ~np.array(straight)
        k = np.array([k for k, line in zip(ks, straight, strict=True) if not line])[:, None]
        th = pose[2] + k * s
        xs[rows] = pose[0] + sign * (np.sin(th) - math.sin(pose[2])) / k
        ys[rows] = pose[1] - sign * (np.cos(th) - math.cos(pose[2])) / k
    hit = _hits(xs, ys, near, radius)
    first = hit.argmax(axis=1).tolist()
    return [float(s[i] - ARC_STEP) if any_hit else horizon
            for i, any_hit in zip(first, hit.any(axis=1).tolist(), strict=True)]


BOX_MARGIN = 1e-6  # m added to the radius around an arc's poses: far above any rounding


def _hits(xs: np.ndarray, ys: np.ndarray, near: np.ndarray, radius: float) -> np.ndarray:
    """(arcs, poses): whether a point of ``near`` is closer than ``radius`` to each pose,
    as ``min((x - px) ** 2 + (y - py) ** 2) < radius ** 2`` over every point decides it.

    A point outside an arc's bounding box of poses widened by radius + BOX_MARGIN is
    farther than the radius from each of them in x or in y by more than rounding, so its
    computed squared distance is at least radius ** 2 and cannot change the minimum's
    comparison: only the pairs of an arc and a point in its box are computed (the same
    operations on the same operands). One arc, short arcs (the box costs more than it
    saves) and points that are not all finite take every pair."""
    r2 = radius * radius
    if len(xs) == 1 or xs.shape[1] < 8 or not np.isfinite(near).all():  # few: all pairs
        return ((xs[:, :, None] - near[:, 0]) ** 2
                + (ys[:, :, None] - near[:, 1]) ** 2).min(axis=2) < r2
    px, py = near[:, 0], near[:, 1]
    wide = radius + BOX_MARGIN
    inside = ((px >= (xs.min(axis=1) - wide)[:, None]) & (px <= (xs.max(axis=1) + wide)[:, None])
              & (py >= (ys.min(axis=1) - wide)[:, None]) & (py <= (ys.max(axis=1) + wide)[:, None]))
    arcs, points = inside.nonzero()  # arcs ascending
    hit = np.zeros(xs.shape, dtype=bool)
    if arcs.size == 0:
        return hit
    d2 = (xs[arcs] - px[points, None]) ** 2 + (ys[arcs] - py[points, None]) ** 2
    first = np.empty(len(arcs), dtype=bool)  # an arc's first pair
    first[0] = True
    np.not_equal(arcs[1:], arcs[:-1], out=first[1:])
    starts = first.nonzero()[0]
    hit[arcs[starts]] = np.minimum.reduceat(d2, starts, axis=0) < r2
    return hit


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
    ks = np.linspace(-max_curvature, max_curvature, 17).tolist()
    clear = arc_clearances(points, pose, speed, [speed * k for k in ks], reach, radius)
    for k, free in zip(ks, clear, strict=True):
        if free < reach:
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
