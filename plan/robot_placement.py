"""The robots: section laid out: named robots, a seeded count in a region, or a USD stage's
robot prims, among the world's obstacles (plan/robots.py says what a swarm is). The world
and the description are read by descriptions/robot_layout.py, which calls this."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from plan.errors import ScenarioError
from plan.model import RobotsSpec
from plan.obstacles import Obstacle, place_problem
from plan.robots import RobotPlacement, robot_namespace

PLACEMENT_TRIES = 400  # seeded draws per robot before the count is declared not to fit


class _Where:
    """Errors for the robots: section of one file."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, key: str, problem: str, accepted: str) -> ScenarioError:
        return ScenarioError(self.path, key, problem, accepted)


def place_robots(path: Path, spec: RobotsSpec, obstacles: list[Obstacle], footprint: float,
                 seed: int, mounts: list[tuple[str, Path, tuple]]) -> list[RobotPlacement]:
    """The robots of the ``robots:`` section placed among the world's ``obstacles``: a USD
    stage's robot ``mounts`` (name, description, (x, y, yaw)) at their prims' poses, the
    ``named`` ones at their starts, or ``count`` of them seeded. Raises ScenarioError naming
    the key: robots that overlap or stand in obstacles, a count that does not fit, two
    robots with one name."""
    where = _Where(path)
    if (spec.count is None) == (spec.named is None):
        raise where.fail("robots", "give exactly one of count (seeded placement) or named "
                         "(a list of robots).", "count: N with region: {x: [x0, x1], y: "
                         "[y0, y1]}, or named: [{name, start: {x, y}, goal: {x, y}}, ...].")
    if mounts:
        robots = _from_stage(where, spec, mounts, obstacles, footprint)
    elif spec.named is not None:
        robots = _named(where, spec, obstacles, footprint)
    else:
        robots = _placed(where, spec, obstacles, footprint, seed)
    return _namespaced(where, spec, robots)


def _namespaced(where: _Where, spec: RobotsSpec, robots: list[RobotPlacement]
                ) -> list[RobotPlacement]:
    """Each robot with its ROS namespace (``plan.robots.robot_namespace``: a lone robot at
    the root unless it names one); two robots in one namespace are refused, at the entry
    whose ``namespace`` key gives it (the later one's where both do)."""
    out: list[RobotPlacement] = []
    taken: dict[str, str] = {}
    entries = {e.name: (i, e) for i, e in enumerate(spec.named or [])}

    def key_of(name: str) -> str | None:
        i, entry = entries.get(name, (None, None))
        return None if entry is None or entry.namespace is None else \
            f"robots.named[{i}].namespace"
    for robot in robots:
        namespace = robot_namespace(spec, robot.name)
        if namespace in taken:
            first = taken[namespace]
            raise where.fail(key_of(robot.name) or key_of(first) or "robots.named",
                             f"robots {first!r} and {robot.name!r} would share the namespace "
                             f"{namespace!r}.", "a distinct namespace per robot.")
        taken[namespace] = robot.name
        out.append(replace(robot, namespace=namespace))
    return out


def _from_stage(where: _Where, spec: RobotsSpec, mounts, obstacles, footprint: float
                ) -> list[RobotPlacement]:
    """The stage's robot prims, each at its prim's pose; ``named`` gives each one's goal."""
    from plan.model import NamedRobot, PlanarPose

    if spec.named is None:
        raise where.fail("robots", f"the world's stage places {len(mounts)} robots; each "
                         "needs a goal.", "named: [{name: <prim name>, goal: {x, y}}, ...], "
                         "one entry per robot prim of the stage.")
    placed = {name: pose for name, _, pose in mounts}
    goals, namespaces = {}, {}
    for i, entry in enumerate(spec.named):
        key = f"robots.named[{i}]"
        if entry.name not in placed:
            raise where.fail(f"{key}.name", f"the stage has no robot prim named {entry.name!r}.",
                             f"one of {', '.join(sorted(placed))}.")
        if entry.start is not None:
            raise where.fail(f"{key}.start", f"the stage places robot {entry.name!r} (its "
                             "prim's pose); a start here would contradict it.",
                             "leave start out.")
        goals[entry.name] = entry.goal
        namespaces[entry.name] = entry.namespace
    missing = [name for name in placed if name not in goals]
    if missing:
        raise where.fail("robots.named", f"no goal for the stage's robot {missing[0]!r}.",
                         "an entry {name, goal} for every robot prim of the stage.")
    named = [NamedRobot(name=name, goal=goals[name], namespace=namespaces[name],
                        start=PlanarPose(x=pose[0], y=pose[1], yaw=pose[2]))
             for name, pose in placed.items()]
    return _named(where, spec.model_copy(update={"named": named}), obstacles, footprint)


def _named(where: _Where, spec: RobotsSpec, obstacles, footprint: float
           ) -> list[RobotPlacement]:
    robots: list[RobotPlacement] = []
    for i, entry in enumerate(spec.named):
        key = f"robots.named[{i}]"
        if entry.start is None:
            raise where.fail(f"{key}.start", f"robot {entry.name!r} has no start.",
                             "start: {x, y, yaw} (only a USD stage's robot prims place "
                             "their robots themselves).")
        for other in robots:
            if other.name == entry.name:
                raise where.fail(f"{key}.name", f"two robots are named {entry.name!r} (one "
                                 "namespace for two robots).", "a distinct name per robot.")
        start = (entry.start.x, entry.start.y, entry.start.yaw)
        goal = (entry.goal.x, entry.goal.y, entry.goal.yaw)
        for part, pose in (("start", start), ("goal", goal)):
            problem = place_problem(obstacles, pose[0], pose[1], footprint)
            if problem:
                raise where.fail(f"{key}.{part}", f"the {part} {problem}.", "a pose inside the "
                                 "world with the robot clear of obstacles.")
            for other in robots:
                there = getattr(other, part)
                gap = math.hypot(pose[0] - there[0], pose[1] - there[1])
                if gap < 2 * footprint:
                    raise where.fail(f"{key}.{part}", f"robot {entry.name!r} would overlap "
                                     f"robot {other.name!r} there ({gap:.3f} m apart, the "
                                     f"robots are {2 * footprint:.3f} m across).",
                                     f"{part}s at least {2 * footprint:.3f} m apart.")
        robots.append(RobotPlacement(entry.name, start, goal))
    return robots


def _placed(where: _Where, spec: RobotsSpec, obstacles, footprint: float, seed: int
            ) -> list[RobotPlacement]:
    """``count`` robots drawn from the scenario seed's own stream ('robots'): each start
    uniformly in ``region`` until one keeps ``clearance`` from the others and its robot
    clear of obstacles, at its start and at its goal; each faces its goal."""
    for key, region in (("region", spec.region), ("goal_region", spec.goal_region)):
        if region is None:
            if key == "region":
                raise where.fail("robots.region", "count needs a region to place the robots in.",
                                 "region: {x: [x0, x1], y: [y0, y1]} in metres.")
            continue
        for axis in ("x", "y"):
            low, high = getattr(region, axis)
            if not low < high:
                raise where.fail(f"robots.{key}.{axis}", f"[{low:g}, {high:g}] is empty.",
                                 "[low, high] with low < high.")
    if spec.clearance < 2 * footprint:
        raise where.fail("robots.clearance", f"{spec.clearance:g} m lets robots overlap: each "
                         f"is {2 * footprint:.3f} m across.", f"at least {2 * footprint:.3f}.")
    rng = np.random.default_rng(_seed(seed))
    region = spec.region
    centre = (sum(region.x) / 2, sum(region.y) / 2)
    starts: list[tuple[float, float]] = []
    goals: list[tuple[float, float]] = []
    apart_starts, apart_goals = _Apart(spec.clearance), _Apart(spec.clearance)
    for _ in range(spec.count * PLACEMENT_TRIES):
        if len(starts) == spec.count:
            break
        start = (float(rng.uniform(*region.x)), float(rng.uniform(*region.y)))
        if spec.goal_region is None:
            goal = (2 * centre[0] - start[0], 2 * centre[1] - start[1])
        else:
            goal = (float(rng.uniform(*spec.goal_region.x)),
                    float(rng.uniform(*spec.goal_region.y)))
        if apart_starts.fits(start) and apart_goals.fits(goal) and not (
                place_problem(obstacles, *start, footprint)
                or place_problem(obstacles, *goal, footprint)):
            starts.append(start)
            goals.append(goal)
            apart_starts.add(start)
            apart_goals.add(goal)
    if len(starts) < spec.count:
        raise where.fail("robots.count", f"only {len(starts)} of {spec.count} robots fit in "
                         f"the region {spec.clearance:g} m apart and clear of obstacles (at "
                         "their starts and goals).", "fewer robots, a larger region or a "
                         "smaller clearance.")
    robots = []
    for i, (start, goal) in enumerate(zip(starts, goals, strict=True)):
        heading = math.atan2(goal[1] - start[1], goal[0] - start[0])
        robots.append(RobotPlacement(f"{spec.name_prefix}_{i}", (*start, heading),
                                     (*goal, heading)))
    return robots


class _Apart:
    """Points kept at least ``gap`` apart. A point is measured against those in the 5 x 5
    cells of side ``gap`` around its own: one in any other cell is more than ``gap`` away
    on one axis, so it could not fail the test (every point was measured against every
    other: a million distances at 1,000 robots). The same distances decide as before."""

    def __init__(self, gap: float):
        self.gap = gap
        self.cells: dict[tuple[int, int], list[tuple[float, float]]] = {}

    def _cell(self, point: tuple[float, float]) -> tuple[int, int]:
        return math.floor(point[0] / self.gap), math.floor(point[1] / self.gap)

    def fits(self, point: tuple[float, float]) -> bool:
        """Whether ``point`` is at least ``gap`` from every point added."""
        cx, cy = self._cell(point)
        return all(math.hypot(point[0] - x, point[1] - y) >= self.gap
                   for i in range(cx - 2, cx + 3) for j in range(cy - 2, cy + 3)
                   for x, y in self.cells.get((i, j), ()))

    def add(self, point: tuple[float, float]) -> None:
        """Keep ``point`` (it fits)."""
        self.cells.setdefault(self._cell(point), []).append(point)


def _seed(scenario_seed: int) -> int:
    """The placement's seed: nodes.contract.node_seed(scenario_seed, 'robots'), the stream
    a node named 'robots' would get (the formula is repeated: plan imports no node code)."""
    import hashlib

    digest = hashlib.sha256(f"{scenario_seed}:robots".encode()).digest()
    return int.from_bytes(digest[:8], "little")


