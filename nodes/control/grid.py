"""An occupancy grid of the world's static geometry, its obstacle distance field, and A*.

The grid is built once from the world (the same file physics loads): every static
obstacle (``plan.obstacles``) that overlaps the robot's height band is rasterised by
its footprint: the true circle of an upright cylinder, capsule or sphere, the rectangle of
a box, the convex hull of anything else.
The distance field holds, per cell, the distance to the nearest occupied cell up to a cap.
"""

from __future__ import annotations

import heapq
import math
from collections import deque

import mujoco
import numpy as np

from descriptions.world_geometry import static_obstacles
from plan.obstacles import Obstacle, polygon_edge_distances

SQRT2 = math.sqrt(2.0)
HEURISTIC_WEIGHT = 1.02  # A*: a plan costs at most 2 % more than the cheapest (see astar)
NEIGHBOURS = [(-1, -1, SQRT2), (-1, 0, 1.0), (-1, 1, SQRT2), (0, -1, 1.0),
              (0, 1, 1.0), (1, -1, SQRT2), (1, 0, 1.0), (1, 1, SQRT2)]


class Grid:
    """A square-cell grid over the xy plane: ``occ[i, j]`` is cell (x index i, y index j)."""

    def __init__(self, origin: tuple[float, float], shape: tuple[int, int], resolution: float):
        self.origin = np.array(origin, dtype=np.float64)
        self.res = resolution
        self.occ = np.zeros(shape, dtype=bool)
        self.dist = np.full(shape, np.inf)
        self.obstacles: list[Obstacle] = []  # what was rasterised, for explanations

    def cell(self, x: float, y: float) -> tuple[int, int]:
        """The index of the cell holding (x, y), clipped to the grid."""
        i = int(np.floor((x - self.origin[0]) / self.res))
        j = int(np.floor((y - self.origin[1]) / self.res))
        return min(max(i, 0), self.occ.shape[0] - 1), min(max(j, 0), self.occ.shape[1] - 1)

    def centre(self, i: int, j: int) -> tuple[float, float]:
        """The world coordinates of a cell's centre."""
        return (self.origin[0] + (i + 0.5) * self.res, self.origin[1] + (j + 0.5) * self.res)

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """World x and y of every cell centre, shaped like the grid."""
        xs = self.origin[0] + (np.arange(self.occ.shape[0]) + 0.5) * self.res
        ys = self.origin[1] + (np.arange(self.occ.shape[1]) + 0.5) * self.res
        return np.meshgrid(xs, ys, indexing="ij")

    def compute_distance(self, cap: float) -> None:
        """Distance (m) from every cell centre to the nearest occupied one, capped at ``cap``."""
        self.dist = cell_distance(self.occ, self.res, cap)

    def obstacle_distance(self, cap: float) -> np.ndarray:
        """Distance (m) from every cell centre to the true footprint of the nearest obstacle
        in ``obstacles`` (0 inside one), capped at ``cap``: exact, where the distance between
        occupied cells errs by up to a cell."""
        dist = np.full(self.occ.shape, cap)
        xs, ys = self.centres()
        for o in self.obstacles:
            x0, y0, x1, y1 = o.bounds()
            i0, j0 = self.cell(x0 - cap, y0 - cap)
            i1, j1 = self.cell(x1 + cap, y1 + cap)
            window = (slice(i0, i1 + 1), slice(j0, j1 + 1))
            near = np.clip(o.distances(xs[window], ys[window]), 0.0, cap)
            np.minimum(dist[window], near, out=dist[window])
        return dist


def cell_distance(occ: np.ndarray, res: float, cap: float) -> np.ndarray:
    """Distance (m) from every cell centre to the nearest ``occ`` cell's centre, capped."""
    n = int(math.ceil(cap / res))
    dist = np.where(occ, 0.0, cap)
    if not occ.any():
        return dist
    nx, ny = occ.shape
    padded = np.zeros((nx + 2 * n, ny + 2 * n), dtype=bool)
    padded[n:n + nx, n:n + ny] = occ
    for di in range(-n, n + 1):
        for dj in range(-n, n + 1):
            d = math.hypot(di, dj) * res
            if d == 0 or d >= cap:
                continue
            shifted = padded[n + di:n + di + nx, n + dj:n + dj + ny]
            np.minimum(dist, np.where(shifted, d, cap), out=dist)
    return dist


def world_grid(model: mujoco.MjModel, resolution: float, z_band: tuple[float, float],
               margin: float = 0.5) -> Grid:
    """Rasterise the static obstacles of ``model`` (at its default pose) into a grid."""
    return obstacle_grid(band_obstacles(model, z_band), resolution, margin)


def band_obstacles(model: mujoco.MjModel, z_band: tuple[float, float]) -> list[Obstacle]:
    """The static obstacles of ``model`` that overlap the height band ``z_band``."""
    return [o for o in static_obstacles(model)
            if o.z_range[1] >= z_band[0] and o.z_range[0] <= z_band[1]]


def obstacle_grid(obstacles: list[Obstacle], resolution: float, margin: float = 0.5) -> Grid:
    """A grid over ``obstacles`` (and ``margin`` around them) with their footprints marked."""
    if not obstacles:
        raise ValueError("the world has no static obstacles to build a map from")
    bounds = np.array([o.bounds() for o in obstacles])
    lo = bounds[:, :2].min(axis=0) - margin
    hi = bounds[:, 2:].max(axis=0) + margin
    shape = tuple(int(v) for v in np.ceil((hi - lo) / resolution))
    grid = Grid((float(lo[0]), float(lo[1])), shape, resolution)
    grid.obstacles = obstacles
    xs, ys = grid.centres()
    for o in obstacles:
        rasterise(o, grid, xs, ys)
    return grid


def rasterise(o: Obstacle, grid: Grid, xs: np.ndarray, ys: np.ndarray) -> None:
    """Mark the cells an obstacle's footprint covers any part of the centre area of."""
    half = 0.5 * grid.res
    x0, y0, x1, y1 = o.bounds()
    i0, j0 = grid.cell(x0 - half, y0 - half)
    i1, j1 = grid.cell(x1 + half, y1 + half)
    wx, wy = xs[i0:i1 + 1, j0:j1 + 1], ys[i0:i1 + 1, j0:j1 + 1]
    if o.is_circle:
        inside = np.hypot(wx - o.centre[0], wy - o.centre[1]) <= o.radius + half
    else:
        inside = polygon_edge_distances(o.polygon, wx, wy) >= -half
    grid.occ[i0:i1 + 1, j0:j1 + 1] |= inside


def astar(cost: np.ndarray, start: tuple[int, int], goal: tuple[int, int],
          flat: list[float] | None = None) -> list[tuple[int, int]] | None:
    """Cheapest 8-connected path over per-cell costs (inf = blocked), or None.

    A move costs its length times the mean of the two cells' costs (each >= 1), so the
    octile distance (the 8-connected path length) is an admissible heuristic; it is weighted
    by HEURISTIC_WEIGHT, so the path costs at most that much more than the cheapest one,
    and the search runs straight at the goal instead of widening over the many near-equal
    ways an open floor offers (26,684 cells expanded for a 27 m plan in a 256-robot arena at
    weight 1, 406 at 1.02, for the same cost). Among equal estimates the deeper node goes
    first, then the lower cell index: deterministic. Cells are flat indices into the grid
    padded with a blocked border, so no move needs a bounds check; ``flat`` is that padded
    grid as a list (``padded_list(cost)``), for a caller that plans many times over one
    costmap.
    """
    nx, ny = cost.shape
    if not (math.isfinite(cost[start]) and math.isfinite(cost[goal])):
        return None
    wy = ny + 2
    if flat is None:
        flat = padded_list(cost)
    moves = [(di * wy + dj, step) for di, dj, step in NEIGHBOURS]
    gi, gj = goal[0] + 1, goal[1] + 1
    s, g = (start[0] + 1) * wy + start[1] + 1, gi * wy + gj
    inf = math.inf
    best = [inf] * len(flat)
    parent = [-1] * len(flat)
    closed = bytearray(len(flat))
    best[s] = 0.0
    heap = [(HEURISTIC_WEIGHT * _octile(start[0] + 1 - gi, start[1] + 1 - gj), -0.0, s)]
    pop, push = heapq.heappop, heapq.heappush
    while heap:
        _, _, k = pop(heap)
        if k == g:
            return _unwind(parent, k, wy)
        if closed[k]:
            continue
        closed[k] = 1
        here = flat[k]
        g0 = best[k]
        for dk, step in moves:
            m = k + dk
            c = flat[m]
            if c == inf or closed[m]:
                continue
            gm = g0 + step * 0.5 * (here + c)
            if gm < best[m]:
                best[m] = gm
                parent[m] = k
                a, b = divmod(m, wy)
                a, b = abs(a - gi), abs(b - gj)
                h = (a - b) + SQRT2 * b if a >= b else (b - a) + SQRT2 * a
                push(heap, (gm + HEURISTIC_WEIGHT * h, -gm, m))
    return None


def padded_list(cost: np.ndarray) -> list[float]:
    """The costmap with a border of blocked cells, flattened to a list (what A* reads)."""
    padded = np.full((cost.shape[0] + 2, cost.shape[1] + 2), np.inf)
    padded[1:-1, 1:-1] = cost
    return padded.ravel().tolist()


def _octile(di: int, dj: int) -> float:
    """The length of the shortest 8-connected path across (di, dj) cells."""
    a, b = abs(di), abs(dj)
    return (a - b) + SQRT2 * b if a >= b else (b - a) + SQRT2 * a


def reachable(passable: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    """The cells reachable from ``start`` over ``passable`` ones, 8-connected as A* moves."""
    nx, ny = passable.shape
    flat = passable.ravel().tolist()
    seen = bytearray(nx * ny)
    first = start[0] * ny + start[1]
    seen[first] = 1
    queue = deque([first])
    steps = [(di, dj, di * ny + dj) for di, dj, _ in NEIGHBOURS]
    while queue:
        k = queue.popleft()
        i, j = divmod(k, ny)
        for di, dj, dk in steps:
            a, b = i + di, j + dj
            if 0 <= a < nx and 0 <= b < ny:
                m = k + dk
                if flat[m] and not seen[m]:
                    seen[m] = 1
                    queue.append(m)
    return np.frombuffer(bytes(seen), dtype=np.uint8).reshape(nx, ny).astype(bool)


def components(passable: np.ndarray) -> np.ndarray:
    """A label per cell: 0 where not passable, else the number (from 1) of its 8-connected
    region of passable cells, so two cells are joined exactly when their labels are equal
    and non-zero: one pass over the grid answers every later reachability question."""
    nx, ny = passable.shape
    wy = ny + 2  # a border of impassable cells: no bounds checks
    padded = np.zeros((nx + 2, wy), dtype=bool)
    padded[1:-1, 1:-1] = passable
    flat = padded.ravel().tolist()
    labels = [0] * len(flat)
    steps = [di * wy + dj for di, dj, _ in NEIGHBOURS]
    label = 0
    for first in np.flatnonzero(padded).tolist():
        if labels[first]:
            continue
        label += 1
        labels[first] = label
        stack = [first]
        while stack:
            k = stack.pop()
            for dk in steps:
                m = k + dk
                if flat[m] and not labels[m]:
                    labels[m] = label
                    stack.append(m)
    out = np.array(labels, dtype=np.int32).reshape(nx + 2, wy)
    return out[1:-1, 1:-1].copy()


def _unwind(parent: list[int], k: int, wy: int) -> list[tuple[int, int]]:
    path = []
    while k != -1:
        i, j = divmod(k, wy)
        path.append((i - 1, j - 1))
        k = parent[k]
    path.reverse()
    return path
