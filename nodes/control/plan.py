"""The global planner: the costmap over the static map (plus marked scan points) and A*."""

from __future__ import annotations

import math

import mujoco
import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from pydantic import BaseModel

from nodes.control.grid import astar, world_grid


class Planner:
    """Costmap (lethal within ``lethal_distance``, decaying cost to ``cost_distance``) + A*."""

    def __init__(self, model: mujoco.MjModel, params: BaseModel):
        self.p = params
        self.grid = world_grid(model, params.resolution, (0.02, 0.6))
        self.static = self.grid.occ.copy()
        self._update_cost()

    def _update_cost(self) -> None:
        p = self.p
        self.grid.compute_distance(max(p.cost_distance, p.lethal_distance) + p.resolution)
        d = self.grid.dist
        span = max(p.cost_distance - p.lethal_distance, 1e-9)
        extra = p.cost_weight * np.clip((p.cost_distance - d) / span, 0.0, 1.0) ** 2
        self.cost = np.where(d < p.lethal_distance, np.inf, 1.0 + extra)

    def mark(self, points: np.ndarray) -> None:
        """Add scan points (odom frame) to the map as obstacles and rebuild the costmap."""
        occ = self.static.copy()
        for x, y in points:
            occ[self.grid.cell(float(x), float(y))] = True
        self.grid.occ = occ
        self._update_cost()

    def plan(self, start: tuple[float, float], goal: tuple[float, float]) -> np.ndarray | None:
        """A (n, 2) path of points from start to goal in the odom frame, or None."""
        s = self._free_near(self.grid.cell(*start))
        g = self._free_near(self.grid.cell(*goal))
        if s is None or g is None:
            return None
        cells = astar(self.cost, s, g)
        if cells is None:
            return None
        pts = np.array([self.grid.centre(i, j) for i, j in cells[::2]] + [goal], dtype=float)
        pts[0] = start
        return pts

    def _free_near(self, cell: tuple[int, int], reach: float = 0.6) -> tuple[int, int] | None:
        """The cell itself when plannable, else the nearest plannable cell within ``reach``."""
        if math.isfinite(self.cost[cell]):
            return cell
        n = int(math.ceil(reach / self.grid.res))
        i0, j0 = max(cell[0] - n, 0), max(cell[1] - n, 0)
        window = self.cost[i0:cell[0] + n + 1, j0:cell[1] + n + 1]
        ii, jj = np.nonzero(np.isfinite(window))
        if ii.size == 0:
            return None
        d = (ii + i0 - cell[0]) ** 2 + (jj + j0 - cell[1]) ** 2
        k = int(np.argmin(d))
        return int(ii[k] + i0), int(jj[k] + j0)


def path_message(path: np.ndarray | None, frame: str, goal_yaw: float) -> Path:
    """nav_msgs/Path of the plan; each pose faces the next point, the last the goal heading."""
    msg = Path()
    msg.header.frame_id = frame
    if path is None:
        return msg
    yaws = np.arctan2(np.diff(path[:, 1]), np.diff(path[:, 0])).tolist() + [goal_yaw]
    for (x, y), yaw in zip(path.tolist(), yaws, strict=True):
        ps = PoseStamped()
        ps.header.frame_id = frame
        ps.pose.position.x, ps.pose.position.y = x, y
        ps.pose.orientation.z, ps.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        msg.poses.append(ps)
    return msg
