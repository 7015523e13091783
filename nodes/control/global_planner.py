"""The global planner: the costmap over the static map (plus marked scan points) and A*.

Two costmaps share one distance field: the normal one keeps the plan ``lethal_distance``
from obstacles; when it has no way, the narrow one lets the plan pass as close as the
robot's radius plus its safety margin (the clearance the local planner drives with), at a
cost that keeps such stretches short. Distances to the static obstacles are measured to
their true footprints; scan points marked during recoveries count by their map cell.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from pydantic import BaseModel

from nodes.control.grid import astar, cell_distance, reachable, world_grid


class Planner:
    """Costmap (lethal within ``lethal_distance``, decaying cost to ``cost_distance``) + A*."""

    def __init__(self, model: mujoco.MjModel, params: BaseModel):
        self.p = params
        self.grid = world_grid(model, params.resolution, (0.02, 0.6))
        self.static = self.grid.occ.copy()
        self.cap = max(params.cost_distance, params.lethal_distance) + params.resolution
        self.static_dist = self.grid.obstacle_distance(self.cap)
        self.marked = np.zeros_like(self.static)
        self.narrow = False  # whether the last plan needed the narrow costmap
        self._update_cost()

    @property
    def narrow_distance(self) -> float:
        """The closest the plan may pass obstacles when nothing wider leads to the goal."""
        p = self.p
        return min(p.lethal_distance, p.robot_radius + p.safety_margin)

    def _update_cost(self) -> None:
        p = self.p
        d = self.static_dist
        if self.marked.any():
            d = np.minimum(d, cell_distance(self.marked, p.resolution, self.cap))
        self.grid.dist = d
        span = max(p.cost_distance - p.lethal_distance, 1e-9)
        extra = p.cost_weight * np.clip((p.cost_distance - d) / span, 0.0, 1.0) ** 2
        self.cost = np.where(d < p.lethal_distance, np.inf, 1.0 + extra)
        self._narrow_cost: np.ndarray | None = None

    @property
    def narrow_cost(self) -> np.ndarray:
        """The costmap that lets the plan through passages narrower than the normal one."""
        if self._narrow_cost is None:
            d = self.grid.dist
            squeeze = 1.0 + 3.0 * self.p.cost_weight
            self._narrow_cost = np.where(d < self.narrow_distance, np.inf,
                                         np.where(d < self.p.lethal_distance, squeeze,
                                                  self.cost))
        return self._narrow_cost

    def mark(self, points: np.ndarray) -> None:
        """Add the scan points (odom frame) the static map does not explain (farther than
        two cells from its obstacles) to the map as obstacles, replacing the last ones, and
        rebuild the costmap. A point on a known obstacle would only add its cell's rounding
        and narrow passages the plan may take."""
        occ = self.static.copy()
        marked = np.zeros_like(self.static)
        for x, y in points:
            cell = self.grid.cell(float(x), float(y))
            if self.static_dist[cell] > 2 * self.p.resolution:
                marked[cell] = True
        self.marked = marked
        self.grid.occ = occ | marked
        self._update_cost()

    def plan(self, start: tuple[float, float], goal: tuple[float, float]) -> np.ndarray | None:
        """A (n, 2) path of points from start to goal in the odom frame, or None."""
        for narrow, cost in ((False, self.cost), (True, self.narrow_cost)):
            s = self.free_near(cost, self.grid.cell(*start))
            g = self.free_near(cost, self.grid.cell(*goal))
            # A flood fill says "no way" in a tenth of the time a failing A* takes.
            if s is None or g is None or not reachable(np.isfinite(cost), s)[g]:
                continue
            cells = astar(cost, s, g)
            if cells is not None:
                self.narrow = narrow
                pts = np.array([self.grid.centre(i, j) for i, j in cells[::2]] + [goal],
                               dtype=float)
                pts[0] = start
                return pts
        return None

    def free_near(self, cost: np.ndarray, cell: tuple[int, int], reach: float = 0.6
                   ) -> tuple[int, int] | None:
        """The cell itself when plannable, else the nearest plannable cell within ``reach``."""
        if math.isfinite(cost[cell]):
            return cell
        n = int(math.ceil(reach / self.grid.res))
        i0, j0 = max(cell[0] - n, 0), max(cell[1] - n, 0)
        window = cost[i0:cell[0] + n + 1, j0:cell[1] + n + 1]
        ii, jj = np.nonzero(np.isfinite(window))
        d = (ii + i0 - cell[0]) ** 2 + (jj + j0 - cell[1]) ** 2
        if ii.size == 0 or d.min() > n * n:
            return None
        k = int(np.argmin(d))
        return int(ii[k] + i0), int(jj[k] + j0)


def path_message(path: np.ndarray | None, frame: str, goal_yaw: float) -> Path:
    """nav_msgs/Path of the plan; each pose faces the next point, the last the goal heading."""
    msg = Path()
    msg.header.frame_id = frame
    if path is None:
        return msg
    # math.atan2, not np.arctan2: numpy's AVX-512 arctan2 rounds differently from its
    # baseline one, so the published path would depend on the CPU.
    yaws = [math.atan2(dy, dx) for dx, dy in np.diff(path, axis=0).tolist()] + [goal_yaw]
    for (x, y), yaw in zip(path.tolist(), yaws, strict=True):
        ps = PoseStamped()
        ps.header.frame_id = frame
        ps.pose.position.x, ps.pose.position.y = x, y
        ps.pose.orientation.z, ps.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        msg.poses.append(ps)
    return msg
