"""An occupancy grid of the world's static geometry, its obstacle distance field, and A*.

The grid is built once from the MJCF (the same file physics loads): every static, colliding
geom that is not the floor and overlaps the robot's height band is rasterised by its exact
footprint (boxes and vertical cylinders/capsules; other shapes by their bounding circle).
The distance field holds, per cell, the distance to the nearest occupied cell up to a cap.
"""

from __future__ import annotations

import heapq
import math

import mujoco
import numpy as np

from nodes.physics.world import static_geoms

GEOM = mujoco.mjtGeom
SQRT2 = math.sqrt(2.0)
NEIGHBOURS = [(-1, -1, SQRT2), (-1, 0, 1.0), (-1, 1, SQRT2), (0, -1, 1.0),
              (0, 1, 1.0), (1, -1, SQRT2), (1, 0, 1.0), (1, 1, SQRT2)]


class Grid:
    """A square-cell grid over the xy plane: ``occ[i, j]`` is cell (x index i, y index j)."""

    def __init__(self, origin: tuple[float, float], shape: tuple[int, int], resolution: float):
        self.origin = np.array(origin, dtype=np.float64)
        self.res = resolution
        self.occ = np.zeros(shape, dtype=bool)
        self.dist = np.full(shape, np.inf)

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
        n = int(math.ceil(cap / self.res))
        dist = np.where(self.occ, 0.0, cap)
        nx, ny = self.occ.shape
        padded = np.zeros((nx + 2 * n, ny + 2 * n), dtype=bool)
        padded[n:n + nx, n:n + ny] = self.occ
        for di in range(-n, n + 1):
            for dj in range(-n, n + 1):
                d = math.hypot(di, dj) * self.res
                if d == 0 or d >= cap:
                    continue
                shifted = padded[n + di:n + di + nx, n + dj:n + dj + ny]
                np.minimum(dist, np.where(shifted, d, cap), out=dist)
        self.dist = dist


def world_grid(model: mujoco.MjModel, resolution: float, z_band: tuple[float, float],
               margin: float = 0.5) -> Grid:
    """Rasterise the static obstacles of ``model`` (at its default pose) into a grid."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    ids = [int(g) for g in np.flatnonzero(static_geoms(model))]
    ids = [g for g in ids if _in_band(model, data, g, z_band)]
    if not ids:
        raise ValueError("the world has no static obstacles to build a map from")
    ext = [np.abs(data.geom_xmat[g].reshape(3, 3)) @ _half_extents(model, g) for g in ids]
    lo = np.min([data.geom_xpos[g, :2] - e[:2] for g, e in zip(ids, ext, strict=True)], 0)
    hi = np.max([data.geom_xpos[g, :2] + e[:2] for g, e in zip(ids, ext, strict=True)], 0)
    lo, hi = lo - margin, hi + margin
    shape = tuple(int(v) for v in np.ceil((hi - lo) / resolution))
    grid = Grid((float(lo[0]), float(lo[1])), shape, resolution)
    xs, ys = grid.centres()
    for g in ids:
        _rasterise(model, data, g, grid, xs, ys)
    return grid


def _in_band(model: mujoco.MjModel, data: mujoco.MjData, g: int, band: tuple[float, float]
             ) -> bool:
    rot = data.geom_xmat[g].reshape(3, 3)
    half = np.abs(rot) @ _half_extents(model, g)
    z = data.geom_xpos[g, 2]
    return z + half[2] >= band[0] and z - half[2] <= band[1]


def _half_extents(model: mujoco.MjModel, g: int) -> np.ndarray:
    s = model.geom_size[g]
    t = model.geom_type[g]
    if t == GEOM.mjGEOM_BOX:
        return s.copy()
    if t == GEOM.mjGEOM_CYLINDER:
        return np.array([s[0], s[0], s[1]])
    if t == GEOM.mjGEOM_CAPSULE:
        return np.array([s[0], s[0], s[1] + s[0]])
    r = model.geom_rbound[g]
    return np.array([r, r, r])


def _rasterise(model: mujoco.MjModel, data: mujoco.MjData, g: int, grid: Grid,
               xs: np.ndarray, ys: np.ndarray) -> None:
    rot = data.geom_xmat[g].reshape(3, 3)
    c = data.geom_xpos[g]
    r = model.geom_rbound[g]
    i0, j0 = grid.cell(c[0] - r, c[1] - r)
    i1, j1 = grid.cell(c[0] + r, c[1] + r)
    sx, sy = xs[i0:i1 + 1, j0:j1 + 1] - c[0], ys[i0:i1 + 1, j0:j1 + 1] - c[1]
    # Cell centres in the geom frame (at the geom's own height).
    lx = rot[0, 0] * sx + rot[1, 0] * sy
    ly = rot[0, 1] * sx + rot[1, 1] * sy
    size = model.geom_size[g]
    t = model.geom_type[g]
    vertical = abs(rot[2, 2]) > 0.999
    half = 0.5 * grid.res  # a cell counts when the shape covers any part of its centre area
    if t == GEOM.mjGEOM_BOX and vertical:
        inside = (np.abs(lx) <= size[0] + half) & (np.abs(ly) <= size[1] + half)
    elif t in (GEOM.mjGEOM_CYLINDER, GEOM.mjGEOM_CAPSULE) and vertical:
        inside = np.hypot(lx, ly) <= size[0] + half
    elif t == GEOM.mjGEOM_SPHERE:
        inside = np.hypot(lx, ly) <= size[0] + half
    else:
        inside = np.hypot(sx, sy) <= r + half
    grid.occ[i0:i1 + 1, j0:j1 + 1] |= inside


def astar(cost: np.ndarray, start: tuple[int, int], goal: tuple[int, int]
          ) -> list[tuple[int, int]] | None:
    """Cheapest 8-connected path over per-cell costs (inf = blocked), or None.

    A move costs its length times the mean of the two cells' costs (each >= 1), so the
    Euclidean heuristic is admissible. Ties break on insertion order: deterministic.
    """
    nx, ny = cost.shape
    flat = cost.ravel().tolist()
    if not (math.isfinite(flat[start[0] * ny + start[1]]) and
            math.isfinite(flat[goal[0] * ny + goal[1]])):
        return None
    gi, gj = goal
    best = {start: 0.0}
    parent: dict[tuple[int, int], tuple[int, int]] = {}
    heap = [(math.hypot(start[0] - gi, start[1] - gj), 0, start)]
    counter = 0
    closed = set()
    while heap:
        _, _, node = heapq.heappop(heap)
        if node == goal:
            return _unwind(parent, node)
        if node in closed:
            continue
        closed.add(node)
        i, j = node
        here = flat[i * ny + j]
        g0 = best[node]
        for di, dj, step in NEIGHBOURS:
            a, b = i + di, j + dj
            if a < 0 or b < 0 or a >= nx or b >= ny:
                continue
            c = flat[a * ny + b]
            if c == math.inf:
                continue
            g = g0 + step * 0.5 * (here + c)
            nxt = (a, b)
            if g < best.get(nxt, math.inf):
                best[nxt] = g
                parent[nxt] = node
                counter += 1
                heapq.heappush(heap, (g + math.hypot(a - gi, b - gj), counter, nxt))
    return None


def _unwind(parent: dict, node: tuple[int, int]) -> list[tuple[int, int]]:
    path = [node]
    while node in parent:
        node = parent[node]
        path.append(node)
    path.reverse()
    return path
