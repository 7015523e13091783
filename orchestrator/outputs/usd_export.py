"""A finished run as an OpenUSD stage (``run.usda``) that usdview and Omniverse play back.

Built after the run from the bag, never during it, so writing cannot change the digest: every
``/cosim/world_state`` message (the whole model's qpos at a physics tick) poses a kinematic copy
of the world (``mj_kinematics``), and MuJoCo's ``mujoco.usd.writer.UsdWriter`` with a
``mujoco.usd.layer_sink.LayerSink`` writes each body's transform as a time sample.

Time codes are tick indices and ``timeCodesPerSecond`` is the tick rate, so time code ``k`` is
sim time ``k * tick``. The stage is the world itself (a USD world is composed in metres, Z up,
and flattened into the file; an MJCF world is written from scratch by the writer), plus
every body MuJoCo knows that the world file does not describe in USD (an MJCF robot:
geometry, joints, actuators, camera) under the default prim, e.g. ``/World/base_link``.

A robot described in URDF, xacro or USD is also written on its own, under its own link and
joint names, as ``robots/ROBOT.usda`` beside the stage (one file for a swarm of copies), in
the layout Isaac Sim's URDF importer writes (``descriptions.usd_robot_write``): a scenario
whose ``robots.description`` names that file runs the same robot again.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from fractions import Fraction
from pathlib import Path

import mujoco
import numpy as np

from descriptions.readers import is_usd_file
from descriptions.swarm_world import swarm_spec
from descriptions.worldfile import compile_world, load_world_spec, open_stage
from plan.timeutil import NS_PER_S, Ns, tick_at_ns

log = logging.getLogger(__name__)

WORLD_STATE = "/cosim/world_state"


def export_run_usd(world: Path, bag: Path, tick_ns: int, out: Path, robots=None) -> Path:
    """Write ``out`` (a .usda/.usdc) from the bag's world states; returns the path. A
    swarm's ``robots`` (plan.robots.RobotsLayout) puts every robot in, as the run had it: an
    MJCF robot as MuJoCo's writer writes it, a URDF, xacro or USD robot as its own asset
    (``robots/ROBOT.usda``, Isaac Sim's importer layout) at ``/World/NAME``, each link posed
    per tick."""
    from mujoco.usd import layer_sink, writer
    from pxr import Gf

    spec = swarm_spec(world, robots) if robots is not None else load_world_spec(world)
    asset = None if robots is None else export_robot_usd(robots, out.parent / "robots")
    scene = spec if asset is None else load_world_spec(world, stage_robots_too=False)
    for light in [li for li in scene.lights if li.name.startswith("/")]:
        scene.delete(light)  # added from UsdLux prims the stage already has
    stage, samples = _stage_for(world, scene)
    model = compile_world(spec, world)  # the run's model: the bag's qpos is its
    data = mujoco.MjData(model)
    scene_model = model if asset is None else compile_world(scene, world)
    scene_data = data if asset is None else mujoco.MjData(scene_model)
    _check_scene_first(scene_model, model)
    usd_writer = writer.UsdWriter(stage, scene, scene_model)
    usd_writer.add_sink(layer_sink.LayerSink(stage).update)
    links = [] if asset is None else _robot_links(stage, asset, robots, model)
    ticks = []
    for tick, qpos in world_states(bag, tick_ns, model.nq):
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        if scene_data is not data:
            scene_data.qpos[:] = qpos[:scene_model.nq]
            mujoco.mj_kinematics(scene_model, scene_data)
        scene_data.time = float(tick)  # LayerSink: time code = data.time * the layer's rate (1)
        usd_writer.update(scene_data)
        for body, translate, orient in links:
            translate.Set(Gf.Vec3d(*data.xpos[body].tolist()), float(tick))
            orient.Set(Gf.Quatd(*data.xquat[body].tolist()), float(tick))
        ticks.append(tick)
    _set_timing(stage, samples, tick_ns, ticks)
    out.parent.mkdir(parents=True, exist_ok=True)
    stage.Export(str(out))
    return out


def _check_scene_first(scene: mujoco.MjModel, model: mujoco.MjModel) -> None:
    """The world's own joints come first in the run's qpos (the robots are attached after
    them), so the world alone is posed from the first ``scene.nq`` values."""
    for j in range(scene.njnt):
        name = scene.joint(j).name
        full = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) if name else -1
        if name and (full < 0 or model.jnt_qposadr[full] != scene.jnt_qposadr[j]):
            raise ValueError(f"the world's joint {name!r} is not where the run's model has it")


def _robot_links(stage, asset: Path, robots, model: mujoco.MjModel) -> list:
    """A prim per robot referencing ``asset`` under the default prim (NAME, or NAME_robot
    where the world has a prim of that name); (body, translate, orient) of each link."""
    from pxr import Gf, UsdGeom, UsdPhysics

    from descriptions.usd_robot_write import prim_name

    top = stage.GetDefaultPrim().GetPath()
    meters = UsdGeom.GetStageMetersPerUnit(stage) or 1.0
    links = []
    for robot in robots.robots:
        path = top.AppendChild(prim_name(robot.name))
        if stage.GetPrimAtPath(path):
            path = top.AppendChild(prim_name(f"{robot.name}_robot"))
        prim = stage.DefinePrim(path, "Xform")
        prim.GetReferences().AddReference(str(asset.resolve()))
        if meters != 1.0:  # the robot is in metres, the world is not
            UsdGeom.Xformable(prim).AddScaleOp().Set(Gf.Vec3f(*[1.0 / meters] * 3))
        for link in prim.GetChildren():
            body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY,
                                     f"{robot.name}/{link.GetName()}")
            if body >= 0 and link.HasAPI(UsdPhysics.RigidBodyAPI):
                links.append((body, link.GetAttribute("xformOp:translate"),
                              link.GetAttribute("xformOp:orient")))
    return links


def export_robot_usd(robots, folder: Path) -> Path | None:
    """The description of ``robots`` (plan.robots.RobotsLayout), when URDF, xacro or USD,
    written as ``folder/ROBOT.usda`` in Isaac Sim's importer layout; None for an MJCF one."""
    from descriptions.readers import load_robot, reader_for
    from descriptions.usd_robot_write import write_robot_usd

    if not reader_for(robots.description).described:
        return None
    loaded = load_robot(robots.description, robots.settings)
    out = folder / f"{loaded.urdf.name or 'robot'}.usda"
    for note in write_robot_usd(loaded, out):
        log.warning("%s: %s", out.name, note)
    return out


def _stage_for(world: Path, spec: mujoco.MjSpec):
    """The stage to write into and its (empty, strongest) sample layer as the edit target."""
    from pxr import Sdf, Usd, UsdGeom

    if is_usd_file(world):
        stage = open_stage(world)
    else:
        stage = Usd.Stage.CreateInMemory()
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    spec.modelname = stage.GetDefaultPrim().GetName()
    samples = Sdf.Layer.CreateAnonymous("cosim-samples.usda")
    samples.timeCodesPerSecond = 1.0
    stage.GetRootLayer().subLayerPaths.insert(0, samples.identifier)
    stage.SetEditTarget(samples)
    return stage, samples


def _set_timing(stage, samples, tick_ns: Ns, ticks: list[int]) -> None:
    """Time code = tick index; rate = ticks per second (both layers agree: no retiming)."""
    rate = float(NS_PER_S / Fraction(tick_ns))
    root = stage.GetRootLayer()
    for layer in (root, samples):
        layer.timeCodesPerSecond = rate
        layer.framesPerSecond = rate
    if ticks:
        root.startTimeCode, root.endTimeCode = float(ticks[0]), float(ticks[-1])
    root.documentation = (f"cosim run: body transforms sampled at every physics tick; time code "
                          f"k = tick k = {tick_ns} ns * k of sim time.")


def world_states(bag: Path, tick_ns: Ns, nq: int) -> Iterator[tuple[int, np.ndarray]]:
    """(tick, qpos) of every /cosim/world_state message in the bag, in order. Objects a
    scenario's events spawned (``plan.events``) come after the world's and the robots' own
    qpos and are not written (the world state names its version then)."""
    from orchestrator.outputs.bag import BagReader

    with BagReader(Path(bag)) as reader:
        for _, stamp, raw in reader.raw([WORLD_STATE]):
            msg = reader.deserialize(raw, WORLD_STATE)
            dims = msg.layout.dim
            edited = any(d.label == "world_version" for d in dims[2:])
            size = dims[0].size if dims else 0
            if not dims or dims[0].label != "qpos" or size < nq or (size > nq and not edited):
                raise ValueError(f"{bag}: {WORLD_STATE} at {stamp} ns does not carry the "
                                 f"world's qpos ({nq} values first)")
            yield tick_at_ns(stamp, tick_ns), np.asarray(msg.data[:nq], dtype=np.float64)
