"""Where a round robot fits, and how far it must drive: a grid search of its own over the
true geometry of generated worlds, independent of the controller's planner and of
``plan.obstacles`` (so a bug there cannot hide behind a check that shares it).

Shapes are upright boxes (rotated about z) and upright cylinders. A cell is free when its
centre is at least ``radius`` from every shape; the robot moves between the centres of
8-neighbouring free cells, diagonally only when both cells beside the diagonal are free too.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Shape:
    """One static obstacle: a box (half sizes ``hx, hy, hz``, turned by ``yaw``) or a
    cylinder (``radius``, half height ``hz``), standing on the floor at (x, y)."""

    name: str
    kind: str  # "box" | "cylinder"
    x: float
    y: float
    hx: float = 0.0
    hy: float = 0.0
    hz: float = 0.5
    yaw: float = 0.0
    radius: float = 0.0

    def distance(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """Distance from points to the footprint (negative inside)."""
        dx, dy = xs - self.x, ys - self.y
        if self.kind == "cylinder":
            return np.hypot(dx, dy) - self.radius
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        qx = np.abs(c * dx + s * dy) - self.hx
        qy = np.abs(-s * dx + c * dy) - self.hy
        outside = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0))
        return outside + np.minimum(np.maximum(qx, qy), 0.0)

    def mjcf(self) -> str:
        """The geom element (class ``obstacle`` of the generated world)."""
        if self.kind == "cylinder":
            return (f'<geom name="{self.name}" class="obstacle" type="cylinder" '
                    f'pos="{self.x:.3f} {self.y:.3f} {self.hz:.3f}" '
                    f'size="{self.radius:.3f} {self.hz:.3f}"/>')
        turn = f' euler="0 0 {math.degrees(self.yaw):.2f}"' if self.yaw else ""
        return (f'<geom name="{self.name}" class="obstacle" pos="{self.x:.3f} {self.y:.3f} '
                f'{self.hz:.3f}" size="{self.hx:.3f} {self.hy:.3f} {self.hz:.3f}"{turn}/>')


class FreeSpace:
    """The cells of a square grid over [-half, half]^2 where a robot of ``radius`` fits."""

    def __init__(self, shapes: list[Shape], half: float, radius: float,
                 resolution: float = 0.05):
        self.res = resolution
        self.half = half
        n = int(round(2 * half / resolution))
        centres = -half + (np.arange(n) + 0.5) * resolution
        self.xs, self.ys = np.meshgrid(centres, centres, indexing="ij")
        clear = np.full(self.xs.shape, np.inf)
        for shape in shapes:
            np.minimum(clear, shape.distance(self.xs, self.ys), out=clear)
        self.clearance = clear  # metres from each cell centre to the nearest obstacle
        # Half a cell more than the radius: between two free centres the robot is never
        # closer to an obstacle than its radius.
        self.free = clear >= radius + 0.5 * resolution

    def cell(self, x: float, y: float) -> tuple[int, int]:
        """The index of the cell holding (x, y)."""
        n = self.free.shape[0]
        i = int(math.floor((x + self.half) / self.res))
        j = int(math.floor((y + self.half) / self.res))
        return min(max(i, 0), n - 1), min(max(j, 0), n - 1)

    def centre(self, i: int, j: int) -> tuple[float, float]:
        """The world coordinates of a cell centre."""
        return float(self.xs[i, j]), float(self.ys[i, j])

    def distances_from(self, x: float, y: float) -> np.ndarray:
        """Shortest driving distance (m) from (x, y) to every cell; inf where unreachable
        (Dijkstra over free cells, no corner cutting)."""
        nx, ny = self.free.shape
        free = self.free.ravel().tolist()
        best = [math.inf] * (nx * ny)
        i, j = self.cell(x, y)
        if not free[i * ny + j]:
            return np.full(self.free.shape, np.inf)
        start = i * ny + j
        best[start] = 0.0
        heap = [(0.0, start)]
        diag = math.sqrt(2.0) * self.res
        while heap:
            d, k = heapq.heappop(heap)
            if d > best[k]:
                continue
            i, j = divmod(k, ny)
            for di in (-1, 0, 1):
                a = i + di
                if a < 0 or a >= nx:
                    continue
                for dj in (-1, 0, 1):
                    b = j + dj
                    if (di == 0 and dj == 0) or b < 0 or b >= ny:
                        continue
                    m = a * ny + b
                    if not free[m]:
                        continue
                    if di and dj:
                        if not (free[a * ny + j] and free[i * ny + b]):
                            continue
                        step = diag
                    else:
                        step = self.res
                    if d + step < best[m]:
                        best[m] = d + step
                        heapq.heappush(heap, (d + step, m))
        return np.array(best).reshape(nx, ny)

    def path_length(self, start: tuple[float, float], goal: tuple[float, float]) -> float:
        """Driving distance from start to goal (inf when no way exists)."""
        return float(self.distances_from(*start)[self.cell(*goal)])
