"""Obstacles seen from above and where a robot fits among them: pure geometry over the
footprints the world loader reads out of a world (``descriptions.world_geometry``). The
planner rasterises them, the load-time checks and the seeded placement measure clearances
against them, the report picture draws them.

A footprint is a circle of its true radius (an upright cylinder, capsule or sphere) or a
convex polygon, counter-clockwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Obstacle:
    """One static obstacle's footprint: a circle (``radius``) or a convex ``polygon``."""

    name: str
    geom: int
    kind: str  # the MuJoCo geom type in lower case: box, cylinder, capsule, sphere, mesh...
    centre: tuple[float, float]
    z_range: tuple[float, float]  # lowest and highest point
    radius: float | None = None  # circles
    polygon: np.ndarray | None = None  # (n, 2) counter-clockwise, for everything else
    visible: bool = True  # in a geom group drawn by default (0-2)

    @property
    def is_circle(self) -> bool:
        """Whether the footprint is a circle."""
        return self.radius is not None

    def distance(self, x: float, y: float) -> float:
        """Distance from (x, y) to the footprint (negative inside)."""
        if self.is_circle:
            return math.hypot(x - self.centre[0], y - self.centre[1]) - self.radius
        return polygon_distance(self.polygon, x, y)

    def distances(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """``distance`` at many points at once (arrays of one shape)."""
        if self.is_circle:
            return np.hypot(xs - self.centre[0], ys - self.centre[1]) - self.radius
        inside = polygon_edge_distances(self.polygon, xs, ys)
        return np.where(inside >= 0, -inside, polygon_outside_distances(self.polygon, xs, ys))

    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the footprint."""
        if self.is_circle:
            cx, cy = self.centre
            return cx - self.radius, cy - self.radius, cx + self.radius, cy + self.radius
        lo, hi = self.polygon.min(axis=0), self.polygon.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2D points, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted({(round(float(x), 9), round(float(y), 9)) for x, y in points})
    if len(pts) < 3:
        return np.array(pts)

    def half(seq):
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2 and _cross(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out[:-1]

    return np.array(half(pts) + half(reversed(pts)))


def _cross(o, a, b) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def polygon_edge_distances(polygon: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Signed distance of points to the line of each edge of a counter-clockwise convex
    polygon (positive inside); the minimum over edges is >= -h exactly for the points
    within h of the polygon, its corners taken square."""
    out = np.full(np.shape(xs), np.inf)
    n = len(polygon)
    for i in range(n):
        ax, ay = polygon[i]
        bx, by = polygon[(i + 1) % n]
        length = math.hypot(bx - ax, by - ay)
        if length == 0:
            continue
        d = ((bx - ax) * (ys - ay) - (by - ay) * (xs - ax)) / length
        np.minimum(out, d, out=out)
    return out


def polygon_outside_distances(polygon: np.ndarray, xs: np.ndarray, ys: np.ndarray
                              ) -> np.ndarray:
    """Distance of points to a polygon's boundary (its nearest edge segment)."""
    best = np.full(np.shape(xs), np.inf)
    n = len(polygon)
    for i in range(n):
        ax, ay = polygon[i]
        bx, by = polygon[(i + 1) % n]
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        t = 0.0 if length2 == 0 else np.clip(((xs - ax) * dx + (ys - ay) * dy) / length2, 0, 1)
        np.minimum(best, np.hypot(xs - ax - t * dx, ys - ay - t * dy), out=best)
    return best


def polygon_distance(polygon: np.ndarray, x: float, y: float) -> float:
    """Distance from (x, y) to a convex polygon (negative inside)."""
    inside = float(polygon_edge_distances(polygon, np.array(x), np.array(y)))
    if inside >= 0:
        return -inside
    best = math.inf
    n = len(polygon)
    for i in range(n):
        ax, ay = polygon[i]
        bx, by = polygon[(i + 1) % n]
        dx, dy = bx - ax, by - ay
        t = 0.0 if dx == dy == 0 else max(0.0, min(1.0, ((x - ax) * dx + (y - ay) * dy)
                                                    / (dx * dx + dy * dy)))
        best = min(best, math.hypot(x - ax - t * dx, y - ay - t * dy))
    return best


def extent(obstacles: list[Obstacle]) -> tuple[float, float, float, float] | None:
    """(xmin, ymin, xmax, ymax) spanned by the obstacles (the world's walls), None if none."""
    if not obstacles:
        return None
    b = np.array([o.bounds() for o in obstacles])
    return float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max())


def place_problem(obstacles: list[Obstacle], x: float, y: float, radius: float,
                  z_band: tuple[float, float] = (0.02, 0.6)) -> str | None:
    """Why a robot of ``radius`` cannot stand at (x, y), or None: outside the world's extent,
    inside an obstacle, or closer to one than its radius (naming the obstacle)."""
    span = extent(obstacles)
    if span is not None and not (span[0] <= x <= span[2] and span[1] <= y <= span[3]):
        return (f"({x:g}, {y:g}) is outside the world, whose obstacles span x {span[0]:g} to "
                f"{span[2]:g} and y {span[1]:g} to {span[3]:g}")
    near = [(o.distance(x, y), o) for o in obstacles
            if o.z_range[1] >= z_band[0] and o.z_range[0] <= z_band[1]]
    if not near:
        return None
    gap, o = min(near, key=lambda item: item[0])
    if gap < 0:
        return f"({x:g}, {y:g}) is inside obstacle {o.name!r} ({o.kind})"
    if gap < radius:
        return (f"({x:g}, {y:g}) is {gap:.3f} m from obstacle {o.name!r} ({o.kind}), closer "
                f"than the robot's radius of {radius:.3f} m")
    return None
