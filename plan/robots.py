"""Many robots in one world: the scenario's ``robots:`` section, checked and laid out.

A swarm scenario names one robot description (an MJCF like ``worlds/robot.xml``) and either
a ``count`` of robots placed from the scenario seed inside a ``region`` (at least
``clearance`` apart, clear of every obstacle, each with a goal in ``goal_region`` or its
start mirrored through the region's centre), or ``named`` robots with their starts and goals.
The world file is the arena only; every process builds the same world from it: the arena
with one copy of the description per robot attached at its start, every name (bodies,
joints, sites, actuators, sensors) prefixed ``ROBOT/`` (``robot_3/base_link``), so the TF
frames read from the bodies carry the REP-105 multi-robot prefix as they are.

Conventions (the README's "Many robots"): each robot's topics live under its namespace
(``/robot_3/odom``, ``/robot_3/scan``, ``/robot_3/cmd_vel``); ``/tf``, ``/tf_static``,
``/clock`` and cosim's own ``/cosim/...`` topics are shared. A node with ``for_each: robot``
becomes one node per robot named ``NAME@ROBOT`` (its own seed stream, as every node's seed
comes from its name) with every topic namespaced; the world node (physics, one MuJoCo
world) takes a ``robots`` parameter with every robot's name and one input per robot.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plan.errors import ScenarioError
from plan.model import InputSpec, NodeSpec, RobotsSpec, ScenarioModel

SHARED_TOPICS = ("/tf", "/tf_static", "/clock")
PLACEMENT_TRIES = 400  # seeded draws per robot before the count is declared not to fit


@dataclass(frozen=True)
class RobotPlacement:
    """One robot: its name (namespace and name prefix), start and goal as (x, y, yaw)."""

    name: str
    start: tuple[float, float, float]
    goal: tuple[float, float, float]


@dataclass(frozen=True)
class RobotsLayout:
    """Every robot of the scenario, where it starts and where it goes, and the description."""

    description: Path
    base_body: str
    robots: tuple[RobotPlacement, ...]
    position_tolerance: float
    yaw_tolerance: float
    success_fraction: float

    @property
    def names(self) -> list[str]:
        """The robots' names in order."""
        return [r.name for r in self.robots]

    def goal_of(self, name: str) -> dict[str, float]:
        """The goal of robot ``name`` as the scenario's ``goal:`` would give it."""
        robot = next(r for r in self.robots if r.name == name)
        x, y, yaw = robot.goal
        return {"x": x, "y": y, "yaw": yaw, "position_tolerance": self.position_tolerance,
                "yaw_tolerance": self.yaw_tolerance}

    @property
    def needed(self) -> int:
        """How many robots must reach their goals for the run to succeed."""
        return max(1, math.ceil(self.success_fraction * len(self.robots) - 1e-9))


def namespaced(robot: str, topic: str) -> str:
    """``topic`` under robot's namespace: '/robot_3/scan'; shared topics stay as they are."""
    if topic in SHARED_TOPICS or topic.startswith("/cosim/"):
        return topic
    return f"/{robot}{topic}"


def robot_of(node_name: str) -> str | None:
    """The robot of a node instance ('control@robot_3' -> 'robot_3'), None for others."""
    return node_name.partition("@")[2] or None


def topic_token(node_name: str) -> str:
    """A node name as a part of a topic name (a topic may not hold '@'):
    'control@robot_3' -> 'control_at_robot_3'."""
    return node_name.replace("@", "_at_")


def prefixed(robot: str, name: str) -> str:
    """A name of the description as it is in the swarm world: 'robot_3/base_link'."""
    return f"{robot}/{name}"


# -- the world ------------------------------------------------------------------------------

@functools.lru_cache(maxsize=4)
def swarm_model(world: Path, layout: RobotsLayout):
    """The compiled swarm world (cached per process: nodes only read the model)."""
    from plan.worldfile import compile_world

    return compile_world(swarm_spec(world, layout), world)


def swarm_spec(world: Path, layout: RobotsLayout):
    """The arena with one prefixed copy of the description per robot, at its start."""
    import mujoco

    from plan.worldfile import load_world_spec

    spec = load_world_spec(world, stage_robots_too=False)  # a stage's robots: attached here
    robot = mujoco.MjSpec.from_file(str(layout.description))
    spec.copy_during_attach = True
    for r in layout.robots:
        x, y, yaw = r.start
        frame = spec.worldbody.add_frame(pos=[x, y, 0.0],
                                         quat=[math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
        spec.attach(robot, frame=frame, prefix=f"{r.name}/")
    return spec


# -- checking and placing --------------------------------------------------------------------

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
        yaw = math.atan2(2 * (w * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
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


# -- node templates --------------------------------------------------------------------------

def expand_nodes(path: Path, model: ScenarioModel, layout: RobotsLayout | None
                 ) -> tuple[ScenarioModel, dict[str, int]]:
    """The model with every ``for_each: robot`` node replaced by one instance per robot
    (``NAME@ROBOT``, parameter ``robot`` set where its class takes one, every topic under
    the robot's namespace) and every other node whose class takes a ``robots`` parameter
    (the world node) given every robot's name and one input per robot. Also returns each
    node's index in the file, by name (an instance's is its template's)."""
    where = _Where(path)
    nodes: list[NodeSpec] = []
    origins: dict[str, int] = {}
    for i, spec in enumerate(model.nodes):
        key = f"nodes[{i}] ({spec.name})"
        if spec.for_each is None:
            if spec.robots is not None:
                raise where.fail(f"{key}.robots", "robots: chooses the robots of a template.",
                                 "for_each: robot with it, or leave robots out.")
            nodes.append(_world_node(spec, layout) if layout else spec)
            origins[spec.name] = i
            continue
        if layout is None:
            raise where.fail(f"{key}.for_each", "the scenario has no robots: section.",
                             "a robots: section, or leave for_each out.")
        chosen = spec.robots or layout.names
        for j, robot in enumerate(chosen):
            if robot not in layout.names:
                raise where.fail(f"{key}.robots[{j}]", f"there is no robot {robot!r}.",
                                 f"one of {', '.join(layout.names[:8])}"
                                 f"{', ...' if len(layout.names) > 8 else ''}.")
        nodes += [_instance(spec, robot) for robot in chosen]
        origins.update({f"{spec.name}@{robot}": i for robot in chosen})
    return model.model_copy(update={"nodes": nodes}), origins


def _class_of(spec: NodeSpec) -> type | None:
    from plan.registry import KINDS, load_class

    ref = KINDS.get(spec.kind) if spec.kind else spec.module
    try:
        return load_class(ref) if ref else None
    except Exception:  # noqa: BLE001 - the scenario's own checks report it, naming the key
        return None


def _instance(spec: NodeSpec, robot: str) -> NodeSpec:
    cls = _class_of(spec)
    params = dict(spec.params)
    if cls is not None and "robot" in getattr(cls.Params, "model_fields", {}):
        params["robot"] = robot
    own = {inp.topic for inp in spec.inputs}
    if cls is not None:
        try:
            checked = cls.Params.model_validate(params)
            own |= set(cls.outputs(checked)) | set(cls.latched_outputs(checked))
        except Exception:  # noqa: BLE001 - reported by the scenario's checks with its key
            pass
    remap = {topic: namespaced(robot, spec.remap.get(topic, topic)) for topic in own}
    remap.update({topic: namespaced(robot, graph) for topic, graph in spec.remap.items()})
    remap = {topic: graph for topic, graph in remap.items() if graph != topic}
    command = spec.command
    if command is not None:
        command = [*command, "--ros-args", "-r", f"__ns:=/{robot}"]
    return spec.model_copy(update={"name": f"{spec.name}@{robot}", "params": params,
                                   "remap": remap, "command": command, "for_each": None,
                                   "robots": None})


def _world_node(spec: NodeSpec, layout: RobotsLayout) -> NodeSpec:
    cls = _class_of(spec)
    if cls is None or "robots" not in getattr(cls.Params, "model_fields", {}):
        return spec
    inputs: list[InputSpec] = []
    for inp in spec.inputs:
        graph = spec.remap.get(inp.topic, inp.topic)
        if namespaced("r", graph) == graph:
            inputs.append(inp)
        else:
            inputs += [InputSpec(topic=namespaced(r, graph), mode=inp.mode) for r in layout.names]
    return spec.model_copy(update={"params": {**spec.params, "robots": layout.names},
                                   "inputs": inputs, "remap": {}})
