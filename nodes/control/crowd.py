"""Crowd navigation: robots that see each other keep clear reciprocally and take turns at doors.

Where the control node gets the physics node's /cosim/world_state it knows the other
robots' poses and velocities (a robot sees another within ``crowd_range`` and in line of
sight on the static map, as its lidar would). Near others it drives by:

- **ORCA** (optimal reciprocal collision avoidance; van den Berg, Guy, Lin and Manocha,
  "Reciprocal n-body collision avoidance", 2011; the linear programs of the RVO2
  library): each robot within ``crowd_horizon`` seconds of a collision bounds the velocity
  by a half-plane; of the avoiding, the earlier name in the scenario's robots takes 0.3 and
  the later 0.7 (a fixed asymmetry breaks symmetric standoffs); a robot parked at its goal
  takes none. Static scan points within reach bound it as obstacles (all of it ours). The
  velocity nearest the pursuit's preferred one is driven as a differential drive does:
  turning towards it, at its speed along the heading (backing up where the half-planes
  demand it). The radius grows by ``crowd_margin`` for what a differential drive cannot
  follow at once (NH-ORCA's tracking error). A robot stalled YIELD_AFTER beside an earlier
  name backs off from it for YIELD_FOR; one stalled beside robots parked at their goals
  plans round them.
- **Doors one way at a time**: a stretch of the plan narrower than two robots side by
  side (a door, a narrow corridor) is used by one direction at a time. A robot waits aside
  (on a grid of places to the right of its way, then the left, out of the way out) while
  another robot is in it facing the other way, or waits beyond its far end facing in with
  an earlier name; a robot inside that meets an earlier name inside facing it backs out;
  robots going the same way go in one at a time (the nearer the entry first). Every robot
  decides from the same poses by the same rule, so both sides of a door agree on who goes;
  a claim not followed within CLAIM_PATIENCE is passed (a robot stuck elsewhere).

A robot among others that comes no nearer its goal (along its plan) for ``crowd_report_s``
says by whom and where (``Crowd.blocked``).
Nothing here reads the wall clock or draws random numbers: the same poses give the same
velocity in any process.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from nodes.physics.messages import world_version

EPS = 1e-9
SECTORS = 24  # scan points taken as static obstacles: the nearest in each of these sectors
STATIC_REACH = 1.0  # m: scan points nearer than this bound the velocity
NEAR = 2.5  # m: a robot nearer than this (or due within the horizon) engages ORCA
DOOR_AHEAD = 3.0  # m along the plan: doors farther than this are not looked at yet
DOOR_EXT = 0.7  # m: the door's zone reaches this far beyond the narrow stretch each way
DOOR_HOLD = 0.8  # m before the zone: where the places to wait begin ...
HOLD_SIDE = (1.0, 2.2, 3.4)  # m: ... this far to the right (then the left) of the plan ...
HOLD_BACK = (0.0, 1.2, 2.4)  # m: ... and this much farther back
HOLD_TAKEN = 0.7  # m: a place with a robot this near (nearer it than we are) is taken
QUEUE = 0.9  # m: a robot this near going into the same door nearer its entry goes first
CLAIM_PATIENCE = 20.0  # s: a robot that claims a door this long and does not come is passed
PROGRESS = 0.3  # m nearer the goal that count as getting on
REPLAN_AFTER = 6.0  # s stalled near a robot parked at its goal before planning round it
YIELD_AFTER = 2.0  # s stalled beside a robot of higher priority before giving way ...
YIELD_FOR = 4.0  # s: ... for this long, backing off from it
SHARE = 0.2  # of the avoiding between two robots, more for the later name, less for the earlier
PASSING = 0.3  # m of room beyond two robots side by side for a passage to be two-way
DOOR_APPROACH = 3.5  # m from the zone's far end: a robot there facing in claims the door
DOOR_SEEN = 0.45  # m from the zone's centre line: a robot this near is in it
FACING = 0.5  # cos of the angle within which a robot faces along (or against) the door


@dataclass
class Line:
    """A half-plane of allowed velocities: left of ``direction`` through ``point``."""

    point: np.ndarray
    direction: np.ndarray


def _dot(a, b) -> float:
    """The dot product of two plane vectors, summed in one fixed order (numpy's ``@`` goes
    to BLAS, whose kernels round differently per CPU: tests/test_architecture.py)."""
    return float(a[0]) * float(b[0]) + float(a[1]) * float(b[1])


def _det(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _lp1(lines: list[Line], n: int, radius: float, opt: np.ndarray, direction_opt: bool
         ) -> np.ndarray | None:
    line = lines[n]
    dot = _dot(line.point, line.direction)
    disc = dot * dot + radius * radius - _dot(line.point, line.point)
    if disc < 0.0:
        return None
    root = math.sqrt(disc)
    t_left, t_right = -dot - root, -dot + root
    for i in range(n):
        denom = _det(line.direction, lines[i].direction)
        numer = _det(lines[i].direction, line.point - lines[i].point)
        if abs(denom) <= EPS:
            if numer < 0.0:
                return None
            continue
        t = numer / denom
        if denom >= 0.0:
            t_right = min(t_right, t)
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return None
    if direction_opt:
        t = t_right if _dot(opt, line.direction) > 0.0 else t_left
    else:
        t = min(max(_dot(line.direction, opt - line.point), t_left), t_right)
    return line.point + t * line.direction


def _lp2(lines: list[Line], radius: float, opt: np.ndarray, direction_opt: bool
         ) -> tuple[int, np.ndarray]:
    if direction_opt:
        result = opt * radius
    elif _dot(opt, opt) > radius * radius:
        result = opt / math.hypot(*opt) * radius
    else:
        result = opt.copy()
    for i, line in enumerate(lines):
        if _det(line.direction, line.point - result) > 0.0:
            found = _lp1(lines, i, radius, opt, direction_opt)
            if found is None:
                return i, result
            result = found
    return len(lines), result


def _lp3(lines: list[Line], n_static: int, begin: int, radius: float, result: np.ndarray
         ) -> np.ndarray:
    distance = 0.0
    for i in range(begin, len(lines)):
        li = lines[i]
        if _det(li.direction, li.point - result) <= distance:
            continue
        projected = lines[:n_static]
        for j in range(n_static, i):
            lj = lines[j]
            determinant = _det(li.direction, lj.direction)
            if abs(determinant) <= EPS:
                if _dot(li.direction, lj.direction) > 0.0:
                    continue
                point = 0.5 * (li.point + lj.point)
            else:
                point = li.point + (_det(lj.direction, li.point - lj.point) / determinant
                                    ) * li.direction
            d = lj.direction - li.direction
            norm = math.hypot(*d)
            if norm <= EPS:
                continue
            projected.append(Line(point, d / norm))
        fail, found = _lp2(projected, radius, np.array([-li.direction[1], li.direction[0]]),
                           True)
        if fail >= len(projected):
            result = found
        distance = _det(li.direction, li.point - result)
    return result


def orca_line(rel_pos: np.ndarray, rel_vel: np.ndarray, velocity: np.ndarray, radius: float,
              horizon: float, step: float, share: float) -> Line:
    """The ORCA half-plane for one neighbour (RVO2's): ``rel_pos`` its position less ours,
    ``rel_vel`` our velocity less its, ``radius`` the two radii together; we take ``share``
    of the avoiding (0.5 between robots, 1 for a static obstacle)."""
    dist_sq = _dot(rel_pos, rel_pos)
    r_sq = radius * radius
    if dist_sq > r_sq:
        w = rel_vel - rel_pos / horizon
        w_sq = _dot(w, w)
        dot1 = _dot(w, rel_pos)
        if dot1 < 0.0 and dot1 * dot1 > r_sq * w_sq:
            w_len = math.sqrt(w_sq)
            unit = w / w_len
            direction = np.array([unit[1], -unit[0]])
            u = (radius / horizon - w_len) * unit
        else:
            leg = math.sqrt(dist_sq - r_sq)
            x, y = rel_pos
            if _det(rel_pos, w) > 0.0:
                direction = np.array([x * leg - y * radius, x * radius + y * leg]) / dist_sq
            else:
                direction = -np.array([x * leg + y * radius, -x * radius + y * leg]) / dist_sq
            u = _dot(rel_vel, direction) * direction - rel_vel
    else:  # already within the radius: get out within one step
        w = rel_vel - rel_pos / step
        w_len = max(math.hypot(*w), EPS)
        unit = w / w_len
        direction = np.array([unit[1], -unit[0]])
        u = (radius / step - w_len) * unit
    return Line(velocity + share * u, direction)


def orca_velocity(lines: list[Line], n_static: int, preferred: np.ndarray, max_speed: float
                  ) -> np.ndarray:
    """The velocity within ``max_speed`` nearest ``preferred`` that every half-plane allows
    (the static ones first and kept hard), or the one that violates them least."""
    fail, result = _lp2(lines, max_speed, preferred, False)
    if fail < len(lines):
        result = _lp3(lines, n_static, fail, max_speed, result)
    return result


class Others:
    """The other robots' poses and velocities, read from /cosim/world_state. The world may
    change at run time (robots and objects entering and leaving): the message says which
    world it shows (``world_version``), and the robots' places in its qpos are read from
    that world (``model_at``); a robot not in it is absent (never seen)."""

    FAR = 1e9  # m: where an absent robot is kept, beyond any crowd_range

    def __init__(self, model_of, names: list[str], own: str, base_suffix: str,
                 goals: np.ndarray, tolerance: float):
        """``model_of(version, label)``: the compiled world a world state of that version
        shows."""
        self.model_of = model_of
        self.names = list(names)
        self.base_suffix = base_suffix
        self.goals, self.tolerance = np.asarray(goals, dtype=np.float64), tolerance
        self.own = self.names.index(own)
        self.world: tuple[int, str] | None = None
        self._addresses(0, "")
        self.xy = np.full((len(names), 2), self.FAR)
        self.vel = np.zeros((len(names), 2))
        self.yaw = np.zeros(len(names))
        self.parked = np.zeros(len(names), dtype=bool)  # at its goal and still
        self.known = False

    def _addresses(self, version: int, label: str) -> None:
        """Each robot's free joint in the world of ``version``/``label`` (absent: none)."""
        model = self.model_of(version, label)
        qpos, qvel, present = [], [], []
        for name in self.names:
            body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY,
                                     f"{name}/{self.base_suffix}")
            joint = model.body_jntadr[body] if body >= 0 else -1
            if body >= 0 and (joint < 0 or model.jnt_type[joint] != mujoco.mjtJoint.mjJNT_FREE):
                raise ValueError(f"robot {name}: no free joint on {name}/{self.base_suffix}")
            present.append(body >= 0)
            qpos.append(model.jnt_qposadr[joint] if body >= 0 else 0)
            qvel.append(model.jnt_dofadr[joint] if body >= 0 else 0)
        self.qpos = np.array(qpos, dtype=np.int64)
        self.qvel = np.array(qvel, dtype=np.int64)
        self.present = np.array(present, dtype=bool)
        self.nq = model.nq
        self.world = (version, label)

    def update(self, msg) -> None:
        """Take the poses and velocities out of a world state (its data: qpos then qvel)."""
        world = world_version(msg)
        if world != self.world:
            self._addresses(*world)
        data = np.asarray(msg.data, dtype=np.float64)
        nq = int(msg.layout.dim[0].size) if msg.layout.dim else self.nq
        if nq != self.nq or not self.present[self.own]:
            self.known = False  # not the world its version names, or this robot not in it
            return
        self.xy = data[self.qpos[:, None] + np.arange(2)]
        q = data[self.qpos[:, None] + np.arange(3, 7)]
        w, x, y, z = q.T
        self.yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        self.vel = data[nq + self.qvel[:, None] + np.arange(2)]
        absent = ~self.present
        self.xy[absent] = self.FAR
        self.vel[absent] = 0.0
        at_goal = np.hypot(*(self.xy - self.goals).T) < self.tolerance
        self.parked = at_goal & (np.hypot(*self.vel.T) < 0.05) & self.present
        self.known = True


class Crowd:
    """One robot's view of the others and its crowd behaviour (ORCA, doors, reports)."""

    def __init__(self, others: Others, planner, params):
        self.others = others
        self.planner = planner
        self.p = params
        self.now_ns = 0
        self._notes: list[str] = []
        self.doors: list[tuple[int, int]] = []  # narrow stretches of the plan: index ranges
        self.along = np.zeros(1)  # m along the plan to each of its points
        self.path: np.ndarray | None = None
        self.best: float | None = None  # m: the nearest to its goal it has come lately ...
        self.blocked_since: int | None = None  # ns: ... since when
        self.reported: str | None = None  # the robot named in the last note
        self.waits = 0  # times this robot held for a door
        self.waiting = False
        self.stalled_since: int | None = None  # ns: engaged and not moving since
        self.yielding: tuple[int, int] | None = None  # (to robot, until ns)
        self.yields = 0
        self.claims: dict[int, int] = {}  # robot -> since when (ns) it claims the next door
        self.replan = False  # stalled by robots parked at their goals: plan round them

    @classmethod
    def of(cls, config, params, planner) -> Crowd:
        """The crowd of a swarm robot's control node: the scenario's robots (its layout),
        their base bodies named as this robot's is under its name."""
        from nodes.physics.world_events import model_at
        from plan.robots import robot_of

        layout = config.layout
        own = robot_of(config.name)
        suffix = params.base_body.split("/", 1)[-1]
        goals = np.array([[layout.goal_of(n)["x"], layout.goal_of(n)["y"]]
                          for n in layout.names])
        world, events = str(config.world), tuple(config.events)
        others = Others(lambda version, label: model_at(world, layout, events, version, label),
                        layout.names, own, suffix, goals, layout.position_tolerance)
        return cls(others, planner, params)

    def update(self, msg, now_ns: int) -> None:
        """Take a world state at time ``now_ns``."""
        self.now_ns = now_ns
        self.others.update(msg)

    def notes(self) -> list[str]:
        """What the robot has to say since it was last asked (who blocks it, where)."""
        out, self._notes = self._notes, []
        return out

    def metrics(self) -> dict[str, float]:
        """door_waits (times it held for a door), yields (times it gave way to a robot
        that it blocked and that blocked it), blocked_s (how long, among robots, since it
        last came PROGRESS nearer its goal along its plan)."""
        held = 0.0 if self.blocked_since is None else (self.now_ns - self.blocked_since) / 1e9
        return {"door_waits": float(self.waits), "yields": float(self.yields),
                "blocked_s": held}

    # -- what the robot sees --------------------------------------------------------------

    def visible(self, pose: tuple[float, float, float]) -> np.ndarray:
        """Indices of the robots this one sees: within crowd_range, in line of sight."""
        o = self.others
        d = np.hypot(o.xy[:, 0] - pose[0], o.xy[:, 1] - pose[1])
        near = np.flatnonzero(d <= self.p.crowd_range)
        near = near[near != o.own]
        if near.size == 0:
            return near
        g = self.planner.grid
        dist = self.planner.static_dist
        t = np.linspace(0.0, 1.0, 2 + int(self.p.crowd_range / g.res))
        xs = pose[0] + (o.xy[near, 0:1] - pose[0]) * t
        ys = pose[1] + (o.xy[near, 1:2] - pose[1]) * t
        i = np.clip(np.floor((xs - g.origin[0]) / g.res).astype(np.int64), 0, dist.shape[0] - 1)
        j = np.clip(np.floor((ys - g.origin[1]) / g.res).astype(np.int64), 0, dist.shape[1] - 1)
        clear = (dist[i, j] > 0.0).all(axis=1)
        return near[clear]

    def around(self, pose: tuple[float, float, float]) -> np.ndarray:
        """Indices of the other robots within crowd_range, seen or not."""
        o = self.others
        d = np.hypot(o.xy[:, 0] - pose[0], o.xy[:, 1] - pose[1])
        near = np.flatnonzero(d <= self.p.crowd_range)
        return near[near != o.own]

    def robot_points(self, points: np.ndarray, seen: np.ndarray) -> np.ndarray:
        """Which scan points lie on a robot this one sees (they are left to ORCA)."""
        if seen.size == 0 or len(points) == 0:
            return np.zeros(len(points), dtype=bool)
        xy = self.others.xy[seen]
        d2 = ((points[:, None, :] - xy[None, :, :]) ** 2).sum(axis=2)
        reach = self.p.robot_radius + 0.12
        return (d2 < reach * reach).any(axis=1)

    # -- doors ------------------------------------------------------------------------------

    def set_path(self, path: np.ndarray | None) -> None:
        """Find the plan's narrow stretches: where the free width across the plan is less
        than two robots side by side (with crowd_margin each) and PASSING."""
        self.path, self.doors = path, []
        self.best = None  # a new plan: its own way to the goal
        if path is not None and len(path):
            seg = np.hypot(np.diff(path[:, 0]), np.diff(path[:, 1]))
            self.along = np.concatenate([[0.0], np.cumsum(seg)])
        if path is None or len(path) < 3:
            return
        g, dist = self.planner.grid, self.planner.static_dist
        tangent = np.gradient(path, axis=0)
        tangent /= np.maximum(np.hypot(tangent[:, 0], tangent[:, 1]), EPS)[:, None]
        normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
        reach = 4 * (self.p.robot_radius + self.p.crowd_margin) + PASSING
        steps = np.arange(g.res, reach + g.res, g.res)
        width = np.zeros(len(path))
        for side in (1.0, -1.0):
            xs = path[:, 0:1] + side * normal[:, 0:1] * steps
            ys = path[:, 1:2] + side * normal[:, 1:2] * steps
            i = np.clip(np.floor((xs - g.origin[0]) / g.res).astype(np.int64), 0,
                        dist.shape[0] - 1)
            j = np.clip(np.floor((ys - g.origin[1]) / g.res).astype(np.int64), 0,
                        dist.shape[1] - 1)
            hit = dist[i, j] <= 0.0
            first = np.where(hit.any(axis=1), hit.argmax(axis=1), len(steps))
            width += np.concatenate([[0.0], steps])[first]
        narrow = width < reach
        edges = np.flatnonzero(np.diff(np.concatenate([[0], narrow.astype(np.int8), [0]])))
        self.doors = [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]

    def door_ahead(self, index: int) -> tuple[int, int, np.ndarray] | None:
        """The next door's zone on the plan (first and last index, its direction), if it
        begins within DOOR_AHEAD of the plan point ``index`` and the robot is not past it."""
        path = self.path
        if path is None:
            return None
        seg = np.hypot(np.diff(path[:, 0]), np.diff(path[:, 1]))
        along = np.concatenate([[0.0], np.cumsum(seg)])
        for a, b in self.doors:
            lo = int(np.searchsorted(along, along[a] - DOOR_EXT))
            hi = int(np.searchsorted(along, along[b] + DOOR_EXT))
            hi = min(hi, len(path) - 1)
            if index > hi:
                continue
            if along[lo] - along[index] > DOOR_AHEAD:
                return None
            d = path[min(b + 1, len(path) - 1)] - path[max(a - 1, 0)]
            n = math.hypot(*d)
            if n <= EPS:
                continue
            return lo, hi, d / n
        return None

    def door_rule(self, pose: tuple[float, float, float], index: int, seen: np.ndarray
                  ) -> tuple[str, int | None]:
        """('go' | 'hold' | 'back' | 'queue', the robot that decides it): the one-way rule
        at the next door (hold: wait aside for the other way; back: out of it; queue: let
        the one nearer its entry go first), among the robots within crowd_range
        (``seen``: a door is looked through, not at); robots parked at their goals are no
        rivals."""
        door = self.door_ahead(index)
        if door is None or seen.size == 0:
            return "go", None
        lo, hi, d = door
        zone = self.path[lo:hi + 1]
        o = self.others
        heading = np.stack([np.cos(o.yaw[seen]), np.sin(o.yaw[seen])], axis=1)
        facing = heading[:, 0] * d[0] + heading[:, 1] * d[1]
        xy = o.xy[seen]
        near = np.sqrt(((xy[:, None, :] - zone[None, :, :]) ** 2).sum(axis=2).min(axis=1))
        inside = near < DOOR_SEEN
        far_end = zone[-1]
        to_end = far_end - xy
        gap = np.hypot(to_end[:, 0], to_end[:, 1])
        beyond = (xy[:, 0] - far_end[0]) * d[0] + (xy[:, 1] - far_end[1]) * d[1] > -0.2
        faces_in = (heading * to_end).sum(axis=1) > FACING * np.maximum(gap, EPS)
        claims = ~inside & beyond & (gap < DOOR_APPROACH) & faces_in
        opposing = (facing < -FACING) & ~o.parked[seen]  # one at its goal is no rival
        me_inside = index >= lo
        mine = o.own
        claiming = {int(k) for n, k in enumerate(seen.tolist()) if opposing[n] and claims[n]}
        self.claims = {k: self.claims.get(k, self.now_ns) for k in claiming}
        patience = round(CLAIM_PATIENCE * 1e9)
        stale = {k for k, since in self.claims.items() if self.now_ns - since > patience}
        rivals = [(int(k), bool(inside[n])) for n, k in enumerate(seen.tolist())
                  if opposing[n] and (inside[n] or (claims[n] and int(k) not in stale))]
        if not rivals:
            if me_inside:
                return "go", None
            # one at a time into the door: a robot going the same way that is nearer its
            # entry (the earlier name among equals) and near this one goes first
            entry = zone[0]
            mine_gap = math.hypot(pose[0] - entry[0], pose[1] - entry[1])
            gaps = np.hypot(xy[:, 0] - entry[0], xy[:, 1] - entry[1])
            close = np.hypot(xy[:, 0] - pose[0], xy[:, 1] - pose[1]) < QUEUE
            first = (gaps < mine_gap - 0.05) | ((np.abs(gaps - mine_gap) <= 0.05)
                                                 & (seen < mine))
            ahead = np.flatnonzero((facing > FACING) & ~inside & close & first
                                   & ~o.parked[seen])
            if ahead.size:
                return "queue", int(seen[ahead[0]])
            return "go", None
        first = min(k for k, _ in rivals)
        if me_inside:
            ahead = [k for k, ins in rivals if ins and k < mine]
            return ("back", min(ahead)) if ahead else ("go", None)
        in_door = [k for k, ins in rivals if ins]
        if in_door:
            return "hold", min(in_door)
        return ("go", None) if mine < first else ("hold", first)

    def hold_point(self, pose: tuple[float, float, float], index: int) -> np.ndarray | None:
        """Where to wait for the next door, out of the way out of it: the first free place
        no robot nearer to it has taken, of a grid that begins DOOR_HOLD before the door's
        zone HOLD_SIDE to the right of the plan (then to its left) and goes back by
        HOLD_BACK (a right-hand rule: both sides wait on their right where there is room)."""
        door = self.door_ahead(index)
        if door is None:
            return None
        lo, _, d = door
        path = self.path
        back = np.hypot(np.diff(path[:lo + 1, 0]), np.diff(path[:lo + 1, 1]))[::-1].cumsum()
        base = path[max(lo - int(np.searchsorted(back, DOOR_HOLD)), 0)]
        right = np.array([d[1], -d[0]])
        g, dist = self.planner.grid, self.planner.static_dist
        o = self.others
        others = np.delete(o.xy, o.own, axis=0)
        here = np.asarray(pose[:2])
        for side in (1.0, -1.0):
            for b in HOLD_BACK:
                for lateral in HOLD_SIDE:
                    spot = base - b * d + side * lateral * right
                    t = np.linspace(0.0, 1.0, 12)[:, None]
                    line = base + t * (spot - base)
                    i = np.clip(np.floor((line[:, 0] - g.origin[0]) / g.res).astype(np.int64),
                                0, dist.shape[0] - 1)
                    j = np.clip(np.floor((line[:, 1] - g.origin[1]) / g.res).astype(np.int64),
                                0, dist.shape[1] - 1)
                    if dist[i[-1], j[-1]] <= self.p.robot_radius + 0.15 or \
                            (dist[i, j] <= 0.0).any():
                        continue
                    mine = math.hypot(*(spot - here))
                    near = np.hypot(others[:, 0] - spot[0], others[:, 1] - spot[1])
                    if ((near < HOLD_TAKEN) & (near < mine)).any():
                        continue
                    return spot
        return base

    # -- reports ----------------------------------------------------------------------------

    def blocked(self, now_ns: int, dist: float, by: int | None, where: str) -> str | None:
        """Count how long the robot has come no nearer its goal (by PROGRESS; ``dist``: how
        far it is now); once that passes crowd_report_s, the note to make (once until it
        gets on), naming the robot that holds it up (``by``: the door rule's, else the
        nearest) and the place."""
        if self.best is None or dist < self.best - PROGRESS:
            self.best, self.blocked_since, self.reported = dist, now_ns, None
            return None
        held = (now_ns - self.blocked_since) / 1e9
        if held < self.p.crowd_report_s or self.reported is not None or by is None:
            return None
        self.reported = self.others.names[by]
        return f"blocked by {self.reported} {where} for {held:.0f} s"

    def steer(self, pose: tuple[float, float, float], target: np.ndarray, dist: float,
              path: np.ndarray, index: int, points: np.ndarray, step_s: float
              ) -> tuple[float, float] | None:
        """(v, w) among other robots: the door rule, then ORCA towards the pursuit
        ``target``; None when no robot is near and the door is free (plain pursuit)."""
        from nodes.control import follow as f

        p = self.p
        if self.path is not path:
            self.set_path(path)
        seen = self.visible(pose)
        rule, by = self.door_rule(pose, index, self.around(pose))
        if rule == "go" and not self.engaged(pose, seen):
            self.best = self.blocked_since = None  # plain navigation: not held by robots
            self.waiting = False
            return None
        on_robot = self.robot_points(points, seen)
        static = points[~on_robot]
        dx, dy = target[0] - pose[0], target[1] - pose[1]
        direction = np.array([dx, dy]) / max(math.hypot(dx, dy), EPS)
        speed = min(p.max_speed, max(p.min_speed, p.approach_gain * dist))
        if rule == "hold":
            spot = self.hold_point(pose, index)
            gap = math.hypot(spot[0] - pose[0], spot[1] - pose[1])
            direction = (spot - np.asarray(pose[:2])) / max(gap, EPS)
            speed = min(speed, gap / p.stop_time) if gap > 0.1 else 0.0
        elif rule == "back":
            direction, speed = -direction, p.backup_speed
        elif rule == "queue":
            speed = 0.0
        giving = self.giving_way(pose, seen, rule)
        if giving is not None:
            away = np.asarray(pose[:2]) - self.others.xy[giving]
            direction, speed = away / max(math.hypot(*away), EPS), p.backup_speed
            rule, by = "yield", giving
        if rule == "hold" and not self.waiting:
            self.waits += 1
        self.waiting = rule == "hold"
        preferred = speed * direction
        u = self.velocity(pose, preferred, static, seen, step_s)
        heading = np.array([math.cos(pose[2]), math.sin(pose[2])])
        reverse = rule in ("back", "yield") or (_dot(u, heading) < 0.0
                                     and math.hypot(*(u - preferred)) > 0.05)
        v, w = differential(u, pose, p, reverse)
        if v == 0.0 and w == 0.0 and speed < 0.02:  # held: face the way on, to show it
            alpha = math.remainder(math.atan2(dy, dx) - pose[2], 2 * math.pi)
            if abs(alpha) > 0.25:
                w = math.copysign(max(min(abs(p.turn_gain * alpha), p.max_turn), 0.25), alpha)
        if v != 0.0:
            radius = p.robot_radius + p.tight_margin
            free = f.arc_clearance(static, pose, v, w, p.horizon, radius)
            close = f.arc_clearance(points[on_robot], pose, v, w, 0.3, radius)
            if close < 0.3:
                free = min(free, close)
            v = math.copysign(min(abs(v), free / p.stop_time), v)
            if abs(v) < 0.01:
                v = 0.0
        stalled = abs(v) < 0.03 and rule in ("go", "queue")
        if not stalled:
            self.stalled_since = None
        elif self.stalled_since is None:
            self.stalled_since = self.now_ns
        if self.stalled_since is not None and \
                self.now_ns - self.stalled_since > REPLAN_AFTER * 1e9 and \
                self.parked_near(pose, seen).size:
            self.replan, self.stalled_since = True, None
        if rule == "go":
            by = self.nearest(pose, seen)
        where = f"at ({_place(pose[0])}, {_place(pose[1])})"
        door = self.door_ahead(index)
        if door is not None and rule != "go":
            mid = path[(door[0] + door[1]) // 2]
            where = f"at the door ({_place(mid[0])}, {_place(mid[1])})"
        left = float(self.along[-1] - self.along[index]) + math.hypot(
            path[index][0] - pose[0], path[index][1] - pose[1])
        note = self.blocked(self.now_ns, left, by, where)
        if note:
            self._notes.append(note)
        return v, w

    def parked_near(self, pose: tuple[float, float, float], seen: np.ndarray) -> np.ndarray:
        """Robots seen within 1.5 m that are parked at their goals."""
        o = self.others
        d = np.hypot(o.xy[seen, 0] - pose[0], o.xy[seen, 1] - pose[1])
        return seen[(d < 1.5) & o.parked[seen]]

    def parked_points(self) -> np.ndarray:
        """Points round every robot parked at its goal, for the map: far enough out that a
        plan past them keeps the distance ORCA keeps from them."""
        o = self.others
        k = np.flatnonzero(o.parked)
        a = np.linspace(0.0, 2 * math.pi, 24, endpoint=False)
        out = 2 * self.p.robot_radius + self.p.crowd_margin - self.p.lethal_distance
        ring = np.stack([np.cos(a), np.sin(a)], axis=1) * max(out, self.p.robot_radius)
        pts = (o.xy[k][:, None, :] + np.concatenate([ring, [[0.0, 0.0]]])[None, :, :])
        return pts.reshape(-1, 2)

    def giving_way(self, pose: tuple[float, float, float], seen: np.ndarray, rule: str
                   ) -> int | None:
        """The robot this one gives way to (backs off from) now, if any: after YIELD_AFTER
        stalled with a robot of higher priority (an earlier name) within reach, for
        YIELD_FOR; two robots that block each other so stop blocking (ORCA alone can)."""
        if self.yielding is not None:
            k, until = self.yielding
            if self.now_ns < until:
                return k
            self.yielding = None
            self.stalled_since = None
        if rule not in ("go", "queue") or self.stalled_since is None:
            return None
        if self.now_ns - self.stalled_since < YIELD_AFTER * 1e9:
            return None
        o = self.others
        reach = 2 * (self.p.robot_radius + self.p.crowd_margin) + 0.4
        d = np.hypot(o.xy[seen, 0] - pose[0], o.xy[seen, 1] - pose[1])
        first = [int(k) for k, dk in zip(seen.tolist(), d.tolist(), strict=True)
                 if dk < reach and k < o.own and not o.parked[k]]
        if not first:
            return None
        self.yielding = (min(first), self.now_ns + round(YIELD_FOR * 1e9))
        self.yields += 1
        return min(first)

    # -- driving ----------------------------------------------------------------------------

    def velocity(self, pose: tuple[float, float, float], preferred: np.ndarray,
                 points: np.ndarray, seen: np.ndarray, step_s: float) -> np.ndarray:
        """The ORCA velocity (world frame) nearest ``preferred``: half-planes for the robots
        seen near (a robot parked at its goal takes no share: all of it is ours) and for the
        nearest static scan point of each sector."""
        p, o = self.p, self.others
        me, vel = o.xy[o.own], o.vel[o.own]
        lines: list[Line] = []
        if len(points):
            rel = points - me
            d = np.hypot(rel[:, 0], rel[:, 1])
            keep = np.flatnonzero(d < STATIC_REACH)
            if keep.size:
                sector = ((np.arctan2(rel[keep, 1], rel[keep, 0]) + math.pi)
                          / (2 * math.pi) * SECTORS).astype(np.int64) % SECTORS
                order = np.lexsort((d[keep], sector))
                first = np.concatenate([[True], np.diff(sector[order]) != 0])
                for k in keep[order[first]].tolist():
                    lines.append(orca_line(rel[k], vel, vel, p.robot_radius + p.tight_margin,
                                           p.crowd_static_horizon, step_s, 1.0))
        n_static = len(lines)
        radius = 2 * (p.robot_radius + p.crowd_margin)
        for k in seen.tolist():
            rel = o.xy[k] - me
            if math.hypot(*rel) > NEAR + radius:
                continue
            if o.parked[k]:  # it stands still: all the avoiding and its margin are ours
                lines.append(orca_line(rel, vel - o.vel[k], vel, radius - p.crowd_margin,
                                       p.crowd_horizon, step_s, 1.0))
                continue
            share = 0.5 + (SHARE if k < o.own else -SHARE)
            lines.append(orca_line(rel, vel - o.vel[k], vel, radius, p.crowd_horizon,
                                   step_s, share))
        return orca_velocity(lines, n_static, preferred, p.max_speed)

    def engaged(self, pose: tuple[float, float, float], seen: np.ndarray) -> bool:
        """Whether a robot seen is near enough for ORCA to drive."""
        if seen.size == 0:
            return False
        d = np.hypot(self.others.xy[seen, 0] - pose[0], self.others.xy[seen, 1] - pose[1])
        return bool((d < NEAR).any())

    def nearest(self, pose: tuple[float, float, float], seen: np.ndarray) -> int | None:
        """The robot seen nearest this one, if any."""
        if seen.size == 0:
            return None
        d = np.hypot(self.others.xy[seen, 0] - pose[0], self.others.xy[seen, 1] - pose[1])
        return int(seen[int(np.argmin(d))])


def _place(x: float) -> str:
    """A coordinate to the decimetre, never '-0.0'."""
    return f"{round(x, 1) + 0.0:.1f}"


def differential(u: np.ndarray, pose: tuple[float, float, float], p, reverse: bool
                 ) -> tuple[float, float]:
    """(v, w) of a differential drive following the velocity ``u``: turn towards it, at its
    speed along the heading; turn in place while it points more than rotate_threshold away
    (unless backing up is allowed and it points backwards)."""
    speed = math.hypot(*u)
    if speed < 0.02:
        return 0.0, 0.0
    err = math.remainder(math.atan2(u[1], u[0]) - pose[2], 2 * math.pi)
    if reverse and abs(err) > math.pi / 2:
        back = math.remainder(err - math.pi, 2 * math.pi)
        v = -min(speed * abs(math.cos(back)), p.backup_speed)
        return v, float(np.clip(p.turn_gain * back, -p.max_turn, p.max_turn))
    w = float(np.clip(p.turn_gain * err, -p.max_turn, p.max_turn))
    if abs(err) > p.rotate_threshold:
        return 0.0, w
    return speed * math.cos(err), w
