"""The robots: section checked against the world and laid out: named robots, a seeded
count in a region, or a USD stage's robot prims (plan/robots.py says what a swarm is)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from plan import poses
from plan.errors import ScenarioError
from plan.model import RobotsSpec, ScenarioModel
from plan.robots import RobotPlacement, RobotsLayout, swarm_model

PLACEMENT_TRIES = 400  # seeded draws per robot before the count is declared not to fit


class _Where:
    """Errors for the robots: section of one file."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, key: str, problem: str, accepted: str) -> ScenarioError:
        return ScenarioError(self.path, key, problem, accepted)


def robots_layout(path: Path, model: ScenarioModel) -> RobotsLayout | None:
    """Check the ``robots:`` section against the world and place the robots (seeded); None
    without one. Raises ScenarioError naming the key: a description that does not load,
    robots that overlap or stand in obstacles, a count that does not fit, two robots with
    one name."""
    spec = model.robots
    if spec is None:
        return None
    where = _Where(path)
    obstacles, world = _arena(where, path, model, spec.base_body)
    mounts = _stage_robots(where, world)
    description = _description(where, path, spec, mounts)
    footprint = _footprint(where, description, spec.base_body)
    if (spec.count is None) == (spec.named is None):
        raise where.fail("robots", "give exactly one of count (seeded placement) or named "
                         "(a list of robots).", "count: N with region: {x: [x0, x1], y: "
                         "[y0, y1]}, or named: [{name, start: {x, y}, goal: {x, y}}, ...].")
    if mounts:
        robots = _from_stage(where, spec, mounts, obstacles, footprint)
    elif spec.named is not None:
        robots = _named(where, spec, obstacles, footprint)
    else:
        robots = _placed(where, spec, obstacles, footprint, model.seed)
    layout = RobotsLayout(description, spec.base_body, tuple(robots), spec.position_tolerance,
                          spec.yaw_tolerance, spec.success_fraction)
    from plan.worldfile import WorldError

    try:
        swarm_model(world, layout)
    except WorldError as exc:
        raise where.fail("robots.description", f"the swarm world does not compile: {exc}",
                         "a description whose names do not clash with the world's.") from None
    return layout


def _description(where: _Where, path: Path, spec: RobotsSpec, mounts) -> Path:
    if spec.description is None:
        files = sorted({str(mjcf) for _, mjcf, _ in mounts})
        if len(files) != 1:
            raise where.fail("robots.description", "no robot description given"
                             + (f", and the stage's robot prims name {len(files)} MJCF files."
                                if files else "."), "description: the MJCF of one robot, "
                             "e.g. worlds/robot.xml (or a USD stage whose robot prims all "
                             "name one).")
        return Path(files[0])
    description = (path.parent / spec.description).resolve()
    if not description.is_file():
        raise where.fail("robots.description", f"{spec.description!r} does not exist (looked "
                         f"for {description}).", "the MJCF of one robot, relative to this "
                         "file, e.g. worlds/robot.xml.")
    return description


def _footprint(where: _Where, description: Path, base_body: str) -> float:
    import mujoco

    from plan.world_geometry import robot_footprint_radius

    try:
        robot = mujoco.MjModel.from_xml_path(str(description))
    except ValueError as exc:
        raise where.fail("robots.description", f"the robot MJCF does not load: "
                         f"{str(exc).strip().splitlines()[0]}", "an MJCF MuJoCo loads alone "
                         "(a <mujoco> file with the robot's bodies and actuators).") from None
    if mujoco.mj_name2id(robot, mujoco.mjtObj.mjOBJ_BODY, base_body) < 0:
        raise where.fail("robots.base_body", f"the description has no body {base_body!r}.",
                         "the name of the robot's root body in the description.")
    return robot_footprint_radius(robot, base_body)


def _arena(where: _Where, path: Path, model: ScenarioModel, base_body: str):
    """The static obstacles of the world file, which must hold no robot of its own."""
    import mujoco

    from plan.world_geometry import static_obstacles
    from plan.worldfile import WorldError, compile_world, load_world_spec

    if model.world is None:
        raise where.fail("world", "a robots: section needs a world (the arena) to put them in.",
                         "world: path to an MJCF or USD arena, relative to this file.")
    world = (path.parent / model.world).resolve()
    if not world.is_file():
        raise where.fail("world", f"world file {model.world!r} does not exist (looked for "
                         f"{world}).", "a path relative to the scenario file.")
    try:
        arena = compile_world(load_world_spec(world, stage_robots_too=False), world)
    except WorldError as exc:
        raise where.fail("world", str(exc), "an MJCF or USD world that MuJoCo loads.") from None
    if mujoco.mj_name2id(arena, mujoco.mjtObj.mjOBJ_BODY, base_body) >= 0:
        raise where.fail("world", f"the world already holds a robot (body {base_body!r}); "
                         "with a robots: section the world is the arena alone.",
                         "a world without <include file=\"robot.xml\"/>.")
    return static_obstacles(arena), world


def _stage_robots(where: _Where, world: Path) -> list[tuple[str, Path, tuple]]:
    """The robot prims of a USD stage (``cosim:robot:mjcf``) as (name, MJCF, (x, y, yaw)):
    named by the prim (``/World/Robots/robot_3`` -> robot_3), at its world pose; [] for an
    MJCF world."""
    from plan.worldfile import WorldError, is_usd, open_stage, stage_robots

    if not is_usd(world):
        return []
    from pxr import Gf, Usd, UsdGeom

    try:
        stage = open_stage(world)
        mounts = stage_robots(stage, world)
    except WorldError as exc:
        raise where.fail("world", str(exc), "a USD stage MuJoCo loads.") from None
    out = []
    for mount in mounts:
        prim = stage.GetPrimAtPath(mount.prim)
        pose = Gf.Transform(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(
            Usd.TimeCode.Default()))
        x, y, _ = pose.GetTranslation()
        q = pose.GetRotation().GetQuat()
        w, (qx, qy, qz) = q.GetReal(), q.GetImaginary()
        yaw = poses.yaw(w, qx, qy, qz)
        out.append((mount.prim.rsplit("/", 1)[-1], mount.mjcf, (float(x), float(y), yaw)))
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
    goals = {}
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
    missing = [name for name in placed if name not in goals]
    if missing:
        raise where.fail("robots.named", f"no goal for the stage's robot {missing[0]!r}.",
                         "an entry {name, goal} for every robot prim of the stage.")
    named = [NamedRobot(name=name, goal=goals[name],
                        start=PlanarPose(x=pose[0], y=pose[1], yaw=pose[2]))
             for name, pose in placed.items()]
    return _named(where, spec.model_copy(update={"named": named}), obstacles, footprint)


def _named(where: _Where, spec: RobotsSpec, obstacles, footprint: float
           ) -> list[RobotPlacement]:
    from plan.world_geometry import place_problem

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
    from plan.world_geometry import place_problem

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
    for _ in range(spec.count * PLACEMENT_TRIES):
        if len(starts) == spec.count:
            break
        start = (float(rng.uniform(*region.x)), float(rng.uniform(*region.y)))
        if spec.goal_region is None:
            goal = (2 * centre[0] - start[0], 2 * centre[1] - start[1])
        else:
            goal = (float(rng.uniform(*spec.goal_region.x)),
                    float(rng.uniform(*spec.goal_region.y)))
        if _fits(start, starts, spec.clearance) and _fits(goal, goals, spec.clearance) and not (
                place_problem(obstacles, *start, footprint)
                or place_problem(obstacles, *goal, footprint)):
            starts.append(start)
            goals.append(goal)
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


def _fits(point: tuple[float, float], placed: list[tuple[float, float]], gap: float) -> bool:
    return all(math.hypot(point[0] - x, point[1] - y) >= gap for x, y in placed)


def _seed(scenario_seed: int) -> int:
    """The placement's seed: nodes.contract.node_seed(scenario_seed, 'robots'), the stream
    a node named 'robots' would get (the formula is repeated: plan imports no node code)."""
    import hashlib

    digest = hashlib.sha256(f"{scenario_seed}:robots".encode()).digest()
    return int.from_bytes(digest[:8], "little")


