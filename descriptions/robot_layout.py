"""The robots: section checked against the world: the arena and its obstacles, a USD
stage's robot prims, the description and its footprint, then the robots placed among the
obstacles (plan/robot_placement.py, pure) and the swarm world compiled once."""

from __future__ import annotations

from pathlib import Path

import mujoco

from descriptions.description_error import DescriptionError, scenario_error
from descriptions.readers import (
    READERS,
    Reader,
    is_usd_file,
    layout_settings,
    load_robot,
    reader_for,
)
from descriptions.swarm_world import swarm_model
from descriptions.world_geometry import robot_footprint_radius, static_obstacles
from descriptions.worldfile import (
    WorldError,
    compile_world,
    load_world_spec,
    open_stage,
    stage_robots,
)
from plan import poses
from plan.errors import ScenarioError
from plan.model import RobotsSpec, ScenarioModel
from plan.robot_placement import place_robots
from plan.robots import RobotsLayout


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
    reader = reader_for(description)
    for other in READERS:  # settings for another format than the description's
        key = other.settings_key
        if key not in (None, reader.settings_key) and getattr(spec, key) is not None:
            raise where.fail(f"robots.{key}", f"{key}: settings for {reader.title} "
                             f"description, not {other.title} one.",
                             f"{key}: only with a {other.files} description.")
    settings, base_body = "", spec.base_body
    if reader.described:
        settings, robot = _described_robot(path, spec, description, reader)
        footprint, base_body = robot.footprint_radius, robot.base_link
    else:
        footprint = _footprint(where, description, spec.base_body)
    robots = place_robots(path, spec, obstacles, footprint, model.seed, mounts)
    layout = RobotsLayout(description, base_body, tuple(robots), spec.position_tolerance,
                          spec.yaw_tolerance, spec.success_fraction, settings)
    try:
        swarm_model(world, layout)
    except WorldError as exc:
        raise where.fail("robots.description", f"the swarm world does not compile: {exc}",
                         "a description whose names do not clash with the world's.") from None
    return layout


def entering_robot(path: Path, entry, key: str, base_body: str) -> tuple[Path, str, str]:
    """A robot an event brings in with its own description (``plan.events.RobotEntry``):
    (the description, its reader's settings, its root body); a ScenarioError naming
    ``key`` (``events[i] (name).robot``) when the file is missing or does not load."""
    where = _Where(path)
    description = (path.parent / entry.description).resolve()
    if not description.is_file():
        raise where.fail(f"{key}.description", f"{entry.description!r} does not exist "
                         f"(looked for {description}).", "the MJCF, URDF, xacro or USD of "
                         "one robot, relative to this file.")
    reader = reader_for(description)
    for other in READERS:
        k = other.settings_key
        if k not in (None, reader.settings_key) and getattr(entry, k) is not None:
            raise where.fail(f"{key}.{k}", f"{k}: settings for {reader.title} description, "
                             f"not {other.title} one.", f"{k}: only with a {other.files} "
                             "description.")
    if not reader.described:
        _footprint(where, description, base_body)
        return description, "", base_body
    try:
        settings, robot = _described_robot(path, entry, description, reader)
    except ScenarioError as exc:
        raise where.fail(f"{key}.description", exc.problem, exc.accepted) from None
    return description, settings, robot.base_link


def _described_robot(path: Path, spec: RobotsSpec, description: Path, reader: Reader):
    """A described robot (URDF, xacro, USD) read with its settings: (the settings as the
    layout carries them, the robot model); its losses said once, here, where its reader
    says them."""
    import sys

    key = reader.settings_key
    section = None if key is None else getattr(spec, key)
    settings = layout_settings(description, section, path.parent)
    try:
        robot = load_robot(description, settings).model
    except DescriptionError as exc:
        where = f"robots.{key}.args.{exc.arg}" if exc.arg and key else "robots.description"
        raise scenario_error(exc, path, where) from None
    if reader.says_notes and robot.notes and (description, settings) not in _SAID:
        _SAID.add((description, settings))
        print(f"cosim: {description.name} read as a {reader.name.upper()} robot; changed or "
              "not kept: " + "; ".join(robot.notes), file=sys.stderr)
    return settings, robot


_SAID: set[tuple[Path, str]] = set()  # the robots whose losses this process has said


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
                         f"for {description}).", "the MJCF, URDF, xacro or USD of one robot, "
                         "relative to this file, e.g. worlds/robot.xml.")
    return description


def _footprint(where: _Where, description: Path, base_body: str) -> float:
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
    if not is_usd_file(world):
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
