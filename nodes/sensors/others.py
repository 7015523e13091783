"""What one robot's sensors see of the other robots of a swarm.

Every robot's geoms are in geom group 3, which the lidar does not cast against (so it never
sees its own body), and the description's lidar plane passes above the chassis anyway. In
a swarm the other robots must show in the scan, so the lidar adds them as what the planner
and the placement treat them as: an upright cylinder of the robot's footprint radius (every
colliding geom of it, seen from above) around each other robot's base, from floor to sky.
A beam returns the nearer of its MuJoCo hit and the first such cylinder it meets.

Since no beam can hit a robot's own geoms, the MuJoCo part of the cast need not look at any
robot: ``StaticWorld`` is the arena without its robots, so mj_multiRay's cost follows the
arena and not the swarm (it visits every body and geom of the model it is given, even the
ones the geom groups leave out: 2.4 ms a 180-beam scan among 64 robots, against a few
microseconds here). Its hits are the same geoms at the same poses: the same ranges.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from descriptions.robot_model import RobotModel
from nodes.physics.world_events import model_at
from plan.events import EventSpec
from plan.robots import RobotsLayout


class OtherRobots:
    """The other robots' bases and their footprint radius, for ray casting as cylinders."""

    def __init__(self, model: mujoco.MjModel, swarm: Sequence[RobotModel], robot: RobotModel):
        """``swarm``: every robot's model (``NodeConfig.swarm``), ``robot`` this lidar's."""
        self.swarm, self.own = swarm, robot.name
        self.radius = robot.footprint_radius
        self._bind(model)

    def _bind(self, model: mujoco.MjModel) -> None:
        """The other robots' base bodies in ``model``: those in the world now (robots enter
        and leave a run; their ids move with every change)."""
        ids, index = _bases_in(model, self.swarm)
        keep = ids >= 0
        if (own := index.get(self.own)) is not None:
            keep[own] = False
        self.bodies = ids[keep]
        self.model = model

    def nearer(self, data: mujoco.MjData, origin: np.ndarray, dirs: np.ndarray,
               dist: np.ndarray, range_max: float) -> np.ndarray:
        """``dist`` (MuJoCo's: -1 for no hit) with each beam shortened to the first other
        robot it meets within ``range_max``."""
        if data.model is not self.model:
            self._bind(data.model)
        if self.bodies.size == 0:
            return dist
        centres = data.xpos[self.bodies, :2] - origin[:2]
        near = np.hypot(centres[:, 0], centres[:, 1]) <= range_max + self.radius
        if not near.any():
            return dist
        c = centres[near]  # (k, 2)
        d = dirs[:, :2]  # (n, 2): the horizontal part of each beam (unit length in 3D)
        beams, robots = self._pairs(d, c)
        if beams.size == 0:
            return dist
        # element by element, no matrix products: the same bits on every CPU; each (beam,
        # robot) pair is computed as every pair was before the others were left out
        a = (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])[beams]
        db, cr = d[beams], c[robots]
        b = db[:, 0] * cr[:, 0] + db[:, 1] * cr[:, 1]  # beam . centre
        cc = ((c[:, 0] * c[:, 0] + c[:, 1] * c[:, 1]) - self.radius ** 2)[robots]
        disc = b * b - a * cc
        with np.errstate(invalid="ignore", divide="ignore"):
            tt = (b - np.sqrt(disc)) / a
        tt = np.where((disc >= 0) & (tt > 0) & (a > 1e-12), tt, np.inf)
        t = np.full(len(d), np.inf)
        np.minimum.at(t, beams, tt)
        hit = t <= range_max
        if not hit.any():
            return dist
        return np.where(hit & ((dist < 0) | (t < dist)), t, dist)

    def _pairs(self, d: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(beam, robot) index pairs that may meet: the beams whose heading lies within the
        robot's angular half-width asin(radius / distance) and PAIR_MARGIN of its centre's,
        every beam for a robot within 1.001 radii. A pair left out cannot hit: its beam
        passes the centre at least about 2 radius distance PAIR_MARGIN wider than the
        radius (its computed discriminant is negative, rounding being some 1e-15 of
        distance squared) or points away (b <= 0, so t <= 0)."""
        n = len(d)
        heading = np.arctan2(d[:, 1], d[:, 0])
        order = np.argsort(heading, kind="stable")
        around = heading[order]
        around = np.concatenate([around - 2 * np.pi, around, around + 2 * np.pi])
        distance = np.hypot(c[:, 0], c[:, 1])
        close = distance <= 1.001 * self.radius
        with np.errstate(invalid="ignore", divide="ignore"):
            half = np.arcsin(np.minimum(1.0, self.radius / distance)) + PAIR_MARGIN
        centre = np.arctan2(c[:, 1], c[:, 0])
        lo = np.searchsorted(around, centre - half, "left")
        hi = np.searchsorted(around, centre + half, "right")
        lo[close], hi[close] = n, 2 * n
        counts = hi - lo
        robots = np.repeat(np.arange(len(c)), counts)
        starts = np.repeat(lo - (np.cumsum(counts) - counts), counts)
        return order[(np.arange(len(robots)) + starts) % n], robots


PAIR_MARGIN = 1e-3  # rad of heading around a robot's disc whose beams are computed


def _bases_in(model: mujoco.MjModel, swarm: Sequence[RobotModel]
              ) -> tuple[np.ndarray, dict[str, int]]:
    """(the base body id in ``model`` of every robot of ``swarm``, in its order, -1 for one
    not in the world now; each robot's place in it by name), looked up once per model and
    swarm of the process: every lidar asks (a thousand lidars looked up a million names)."""
    key = (id(model), id(swarm))
    held = _BASE_IDS.get(key)
    if held is None or held[0] is not model or held[1] is not swarm:
        ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, r.base)
                        for r in swarm], dtype=np.int64)
        held = (model, swarm, ids, {r.name: i for i, r in enumerate(swarm)})
        if len(_BASE_IDS) >= 4:
            _BASE_IDS.clear()
        _BASE_IDS[key] = held
    return held[2], held[3]


_BASE_IDS: dict[tuple[int, int], tuple] = {}
"""_bases_in by (model, swarm) id, each kept with its model and swarm (their ids are not
reused meanwhile)."""


class StaticWorld:
    """The swarm's arena without its robots, posed like the swarm's mirror: what a lidar
    casts its beams against (the other robots come from ``OtherRobots``); with the
    scenario's events, the arena of the version the mirror shows."""

    @classmethod
    def shared(cls, world: Path | str, layout: RobotsLayout, full: mujoco.MjModel,
               events: tuple[EventSpec, ...] = ()) -> StaticWorld:
        """The process's one arena for the mirror ``WorldMirror.shared`` gives (its model
        ``full``): the lidars of a swarm packed into one process share it as they share the
        mirror (each poses it from the mirror before it casts: the same qpos and version
        give the same arena), instead of an MjData each."""
        key = (str(world), layout, tuple(events))
        held = _ARENAS.get(key)
        if held is None:
            held = _ARENAS[key] = cls(world, layout, full, events)
        return held

    def __init__(self, world: Path | str, layout: RobotsLayout, full: mujoco.MjModel,
                 events: tuple[EventSpec, ...] = ()):
        self.world, self.events = str(world), tuple(events)
        self.layout = dataclasses.replace(layout, robots=())
        self.version, self.label = 0, ""
        self._build(full)

    def _build(self, full: mujoco.MjModel) -> None:
        self.model = model_at(self.world, self.layout, self.events, self.version, self.label)
        self.data = mujoco.MjData(self.model)
        # the arena's own joints (a door, a loose box) by name in the swarm's qpos
        src, dst = [], []
        for j in range(self.model.njnt):
            name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_JOINT, j)
            k = mujoco.mj_name2id(full, mujoco.mjtObj.mjOBJ_JOINT, name or "")
            if name is None or k < 0:
                raise ValueError(f"the arena's joint {j} ({name!r}) is not in the swarm world")
            width = _qpos_width(self.model.jnt_type[j])
            a, b = int(self.model.jnt_qposadr[j]), int(full.jnt_qposadr[k])
            dst.extend(range(a, a + width))
            src.extend(range(b, b + width))
        self.src = np.array(src, dtype=np.int64)
        self.dst = np.array(dst, dtype=np.int64)
        mujoco.mj_kinematics(self.model, self.data)

    def update(self, qpos: np.ndarray, version: int = 0, full: mujoco.MjModel | None = None,
               label: str = "") -> None:
        """Pose the arena's movable parts from the swarm's qpos (nothing to do without);
        first follow the mirror to the world it shows (``version`` and ``label``, its model
        ``full``)."""
        if (version, label) != (self.version, self.label):
            self.version, self.label = version, label
            self._build(full)
        if self.src.size:
            self.data.qpos[self.dst] = qpos[self.src]
            mujoco.mj_kinematics(self.model, self.data)


_ARENAS: dict[tuple, StaticWorld] = {}
"""StaticWorld.shared by (world, layout, events)."""


def _qpos_width(kind: int) -> int:
    return {int(mujoco.mjtJoint.mjJNT_FREE): 7,
            int(mujoco.mjtJoint.mjJNT_BALL): 4}.get(int(kind), 1)
