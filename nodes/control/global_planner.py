"""The global planner: the costmap over the static map (plus marked scan points) and A*.

Two costmaps share one distance field: the normal one keeps the plan ``lethal_distance``
from obstacles; when it has no way, the narrow one lets the plan pass as close as the
robot's radius plus its safety margin (the clearance the local planner drives with), at a
cost that keeps such stretches short. Distances to the static obstacles are measured to
their true footprints; scan points marked during recoveries count by their map cell.

The static map (grid, distance field, both costmaps and which cells each costmap joins) is
built once per process for a world and map parameters and shared, read-only, by every
planner over it: a swarm's controllers packed in one process build it once, not once each.
A planner that marks scan points makes its own costmaps from then on.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
from geometry_msgs.msg import Pose, PoseStamped
from nav_msgs.msg import Path
from pydantic import BaseModel

from nodes.control.grid import (
    Grid,
    astar,
    band_obstacles,
    cell_distance,
    components,
    obstacle_grid,
    padded_list,
)
from nodes.physics import fast_messages as fm
from plan.obstacles import Obstacle

Z_BAND = (0.02, 0.6)  # m: obstacles in this height band are on the map
SHARED_MAPS = 4  # static maps a process keeps (one per world and map parameters)
_shared: dict[tuple, StaticMap] = {}
_by_model: dict[tuple, tuple] = {}  # (id(model), settings) -> (model, its StaticMap)


@dataclass
class StaticMap:
    """What every planner over one world with the same map parameters shares (read-only)."""

    grid: Grid
    dist: np.ndarray  # distance from each cell to the nearest obstacle's footprint, capped
    cost: np.ndarray
    narrow_cost: np.ndarray
    derived: dict[tuple[str, bool], object] = field(default_factory=dict)  # see Planner.derived


def static_map(model: mujoco.MjModel, params: BaseModel) -> StaticMap:
    """The shared static map of ``model``'s obstacles for these map parameters, built on first
    use. The key is the obstacles themselves, not the file, so a world rewritten in place
    gets its own map."""
    keys = ("resolution", "lethal_distance", "cost_distance", "cost_weight", "robot_radius",
            "safety_margin")
    settings = tuple(getattr(params, k) for k in keys)
    same = _by_model.get((id(model), settings))  # the swarm's nodes share one model
    if same is not None and same[0] is model:
        return same[1]
    obstacles = band_obstacles(model, Z_BAND)
    key = (settings, tuple(_obstacle_key(o) for o in obstacles))
    found = _shared.get(key)
    if found is not None:
        _remember(model, settings, found)
        return found
    grid = obstacle_grid(obstacles, params.resolution)
    cap = max(params.cost_distance, params.lethal_distance) + params.resolution
    dist = grid.obstacle_distance(cap)
    grid.dist = dist
    cost, narrow = costmaps(dist, params)
    for a in (grid.occ, dist, cost, narrow):
        a.flags.writeable = False
    if len(_shared) >= SHARED_MAPS:
        _shared.pop(next(iter(_shared)))
    found = _shared[key] = StaticMap(grid, dist, cost, narrow)
    _remember(model, settings, found)
    return found


def _remember(model: mujoco.MjModel, settings: tuple, found: StaticMap) -> None:
    if len(_by_model) >= SHARED_MAPS:
        _by_model.pop(next(iter(_by_model)))
    _by_model[(id(model), settings)] = (model, found)


def _obstacle_key(o: Obstacle) -> tuple:
    return (o.name, o.geom, o.kind, o.centre, o.z_range, o.radius,
            None if o.polygon is None else o.polygon.tobytes())


def costmaps(d: np.ndarray, p: BaseModel) -> tuple[np.ndarray, np.ndarray]:
    """(normal, narrow) costmaps over the distance field ``d``: the normal one is lethal
    within ``lethal_distance``, the narrow one only within the robot's radius plus its
    safety margin, at a cost that keeps such stretches short."""
    span = max(p.cost_distance - p.lethal_distance, 1e-9)
    extra = p.cost_weight * np.clip((p.cost_distance - d) / span, 0.0, 1.0) ** 2
    cost = np.where(d < p.lethal_distance, np.inf, 1.0 + extra)
    squeeze = 1.0 + 3.0 * p.cost_weight
    narrow_distance = min(p.lethal_distance, p.robot_radius + p.safety_margin)
    narrow = np.where(d < narrow_distance, np.inf,
                      np.where(d < p.lethal_distance, squeeze, cost))
    return cost, narrow


class Planner:
    """Costmap (lethal within ``lethal_distance``, decaying cost to ``cost_distance``) + A*."""

    def __init__(self, model: mujoco.MjModel, params: BaseModel):
        self.p = params
        shared = static_map(model, params)
        self.grid = copy.copy(shared.grid)  # its own occ and dist once it marks points
        self.static = shared.grid.occ
        self.cap = max(params.cost_distance, params.lethal_distance) + params.resolution
        self.static_dist = shared.dist
        self.marked = np.zeros_like(self.static)
        self.narrow = False  # whether the last plan needed the narrow costmap
        self.shared = shared
        self.cost, self.narrow_cost = shared.cost, shared.narrow_cost
        self.derived = shared.derived

    @property
    def narrow_distance(self) -> float:
        """The closest the plan may pass obstacles when nothing wider leads to the goal."""
        p = self.p
        return min(p.lethal_distance, p.robot_radius + p.safety_margin)

    def _update_cost(self) -> None:
        p = self.p
        if not self.marked.any():  # back to the static map
            self.grid.dist = self.static_dist
            self.cost, self.narrow_cost = self.shared.cost, self.shared.narrow_cost
            self.derived = self.shared.derived
            return
        d = np.minimum(self.static_dist, cell_distance(self.marked, p.resolution, self.cap))
        self.grid.dist = d
        self.cost, self.narrow_cost = costmaps(d, p)
        self.derived = {}

    def joined(self, narrow: bool, start: tuple[int, int], goal: tuple[int, int]) -> bool:
        """Whether the (narrow) costmap joins two cells: one flood fill of the whole map per
        costmap, then a look-up (a flood fill says "no way" in a tenth of the time a failing
        A* takes; the labels answer every robot's question after the first)."""
        labels = self.derived_of("labels", narrow)
        return bool(labels[start] != 0 and labels[start] == labels[goal])

    def derived_of(self, what: str, narrow: bool):
        """What is computed from a costmap once and kept with it (shared with every planner
        while it is the static one): ``labels`` (its regions, ``components``) or ``flat``
        (the list A* reads, ``padded_list``)."""
        key = (what, narrow)
        found = self.derived.get(key)
        if found is None:
            cost = self.narrow_cost if narrow else self.cost
            found = self.derived[key] = (components(np.isfinite(cost)) if what == "labels"
                                         else padded_list(cost))
        return found

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
            if s is None or g is None or not self.joined(narrow, s, g):
                continue
            cells = astar(cost, s, g, self.derived_of("flat", narrow))
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
        msg.poses.append(_pose_stamped(frame, x, y, math.sin(yaw / 2), math.cos(yaw / 2)))
    return msg


def _pose_stamped(frame: str, x: float, y: float, qz: float, qw: float) -> PoseStamped:
    """``PoseStamped()`` with its header's frame, position (x, y) and orientation's z and w
    set, built into its slots as ``nodes.physics.fast_messages`` builds (rclpy's constructor
    makes every nested default: most of a long plan's cost); the same message."""
    pose = Pose.__new__(Pose)
    pose._check_fields = fm.CHECK
    pose._position = fm.point(x, y, 0.0)
    pose._orientation = fm.quaternion(qw, 0.0, 0.0, qz)
    ps = PoseStamped.__new__(PoseStamped)
    ps._check_fields = fm.CHECK
    ps._header = fm.header(frame)
    ps._pose = pose
    return ps
