"""One loader for every world file (MJCF or OpenUSD); physics, sensors and control all use it.

An MJCF world (``.xml``) is compiled as it is. A USD world (``.usda``, ``.usdc``, ``.usd``) is
read by MuJoCo's own USD importer (``mujoco.MjSpec.from_file``, from the ``mujoco[usd]``
extra), with what the importer lacks added here:

- stage units and up axis: the importer keeps the stage's units (a stage in centimetres
  gives a 100x larger world) and its up axis (Y-up gives sideways gravity). The stage is
  composed under an in-memory root layer (metres, Z-up) that prepends a unit scale and a
  Y-to-Z rotation to every root prim, so the model is always in metres with +Z up;
- robots from MJCF: any prim with the attribute ``asset cosim:robot:mjcf = @robot.xml@``
  (for example ``/World/Robot``) gets that MJCF attached at the prim's world pose
  (``MjSpec.attach`` at a frame, no name prefix, so joint and body names stay as in the MJCF);
- robots described in USD: a prim referencing a robot asset (``PhysicsArticulationRootAPI``
  inside, as Isaac Sim's ``add_reference_to_stage`` places one) is left out of the import; a
  robots: section runs it (descriptions/usd_robot.py), at the prim's pose;
- lights: ``UsdLux`` distant and sphere lights become MuJoCo lights (the importer skips them);
- checks: colliders, rigid bodies and joints the importer would drop silently or mistake
  (a cone, a collider on an Xform, a non-Z plane, a spherical or D6 joint, ...) are refused
  with a :class:`WorldError` naming the file, the prim path and the reason.

Geoms and bodies read from USD are named by their prim path (``/World/Obstacles/Cube_01``).
Everybody calls the same functions with the same file, so every node sees the same model:
same bodies, geoms and qpos in the same order.
"""

from __future__ import annotations

import re
import sys
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from descriptions.readers import is_usd_file
from plan.errors import WorldError

ROBOT_ATTR = "cosim:robot:mjcf"
PREFIX_ATTR = "cosim:robot:prefix"
SUPPORTED_COLLIDERS = ("Cube", "Sphere", "Cylinder", "Capsule", "Plane", "Mesh")
SUPPORTED_JOINTS = ("PhysicsRevoluteJoint", "PhysicsPrismaticJoint", "PhysicsFixedJoint")
# USD carries no MuJoCo <visual>; USD worlds get the settings the MJCF worlds use.
VISUAL = {"shadowsize": 0, "znear": 0.01, "zfar": 50.0}


@dataclass(frozen=True)
class RobotMount:
    """An MJCF robot attached to a USD world at a prim's pose."""

    mjcf: Path
    prim: str
    prefix: str = ""


def load_world_model(path: Path | str) -> mujoco.MjModel:
    """Compile the world (MJCF or USD); a :class:`WorldError` saying why when it cannot."""
    if not is_usd_file(path):
        try:
            return mujoco.MjModel.from_xml_path(str(path))
        except ValueError as exc:
            raise WorldError(path, f"the MJCF does not load: {_one_line(exc)}") from exc
    return compile_world(load_world_spec(path), path)


def load_world_spec(path: Path | str, robots: list[RobotMount] | None = None,
                    stage_robots_too: bool = True) -> mujoco.MjSpec:
    """The world as an uncompiled MjSpec: USD import, MJCF robots attached, lights added.

    ``robots`` adds mounts to those the stage names with ``cosim:robot:mjcf`` attributes;
    ``stage_robots_too=False`` leaves the stage's out (a swarm attaches them itself,
    prefixed: descriptions.swarm_world).
    """
    path = Path(path).resolve()
    if not is_usd_file(path):
        return _mjcf_spec(path)
    stage = open_stage(path)
    usd_robots = _set_aside_usd_robots(stage)
    if stage_robots_too and usd_robots:
        raise WorldError(path, f"the prim references a robot described in USD "
                         f"({usd_robots[0].mjcf.name}); such a robot runs from a robots: "
                         "section (its description defaults to the asset, its start to the "
                         "prim's pose).", usd_robots[0].prim)
    check_stage(stage, path)
    spec = _import(stage, path)
    named = [m for m in stage_robots(stage, path) if not is_usd_file(m.mjcf)] \
        if stage_robots_too else []
    for mount in [*named, *(robots or [])]:
        _attach_robot(spec, stage, mount, path)
    add_lights(spec, stage)
    spec.visual.quality.shadowsize = VISUAL["shadowsize"]
    spec.visual.map.znear, spec.visual.map.zfar = VISUAL["znear"], VISUAL["zfar"]
    return spec


def check_world(path: Path | str) -> mujoco.MjModel:
    """Load and compile the world once; raise :class:`WorldError` naming what is wrong."""
    return load_world_model(path)


def open_stage(path: Path | str):
    """The USD stage composed in metres with +Z up (an in-memory root layer over the file)."""
    from pxr import Sdf, Tf, Usd, UsdGeom

    path = Path(path).resolve()
    try:
        Sdf.Layer.FindOrOpen(str(path))  # its parse errors carry file:line:col
        source = Usd.Stage.Open(str(path), Usd.Stage.LoadAll)
    except Tf.ErrorException as exc:
        raise WorldError(path, f"not a readable USD stage: {_tf_reason(exc)}") from exc
    root = Sdf.Layer.CreateAnonymous("cosim-world.usda")
    root.subLayerPaths.append(str(path))
    stage = Usd.Stage.Open(root)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    if source.HasDefaultPrim():
        root.defaultPrim = source.GetDefaultPrim().GetName()
    root.timeCodesPerSecond = source.GetTimeCodesPerSecond()
    _normalise_roots(stage, UsdGeom.GetStageMetersPerUnit(source),
                     UsdGeom.GetStageUpAxis(source))
    return stage


def _normalise_roots(stage, meters_per_unit: float, up_axis: str) -> None:
    """Prepend a unit scale and a Y-up-to-Z-up rotation to every root Xformable."""
    from pxr import UsdGeom

    if meters_per_unit == 1.0 and up_axis == UsdGeom.Tokens.z:
        return
    for prim in stage.GetPseudoRoot().GetChildren():
        if not prim.IsA(UsdGeom.Xformable):
            continue
        xf = UsdGeom.Xformable(prim)
        order = [str(op) for op in (xf.GetXformOpOrderAttr().Get() or [])]
        ops = []
        if up_axis == UsdGeom.Tokens.y:
            ops.append(xf.AddRotateXOp(opSuffix="cosimUpAxis"))
            ops[-1].Set(90.0)
        if meters_per_unit != 1.0:
            ops.append(xf.AddScaleOp(opSuffix="cosimUnits"))
            ops[-1].Set((meters_per_unit,) * 3)
        xf.GetXformOpOrderAttr().Set([op.GetOpName() for op in ops] + order)


def check_stage(stage, path: Path) -> None:
    """Refuse colliders, bodies and joints MuJoCo's importer drops or mistakes."""
    from pxr import UsdPhysics

    for prim in stage.Traverse():
        where = str(prim.GetPath())
        if not prim.GetPrimTypeInfo().GetSchemaType() and prim.GetTypeName():
            raise WorldError(path, f"unknown prim type {prim.GetTypeName()!r} (its schema "
                             "is not registered).", where)
        if prim.HasAPI(UsdPhysics.CollisionAPI):
            _check_collider(prim, path)
        if prim.IsA(UsdPhysics.Joint) and prim.GetTypeName() not in SUPPORTED_JOINTS:
            raise WorldError(path, f"joint type {prim.GetTypeName()} is not supported by "
                             f"MuJoCo's USD importer (it drops it); use one of "
                             f"{', '.join(SUPPORTED_JOINTS)}.", where)


def _check_collider(prim, path: Path) -> None:
    """A collider must be a gprim MuJoCo imports: a Z plane, cube, sphere, ..."""
    kind = prim.GetTypeName()
    where = str(prim.GetPath())
    if kind not in SUPPORTED_COLLIDERS:
        raise WorldError(path, f"PhysicsCollisionAPI on a {kind or 'typeless'} prim: MuJoCo's "
                         f"USD importer makes colliders only of {', '.join(SUPPORTED_COLLIDERS)}.",
                         where)
    if kind == "Plane" and prim.GetAttribute("axis").Get() not in (None, "Z"):
        raise WorldError(path, "a collision Plane must have axis \"Z\" (MuJoCo planes are "
                         "z-up; rotate the prim instead).", where)


def _import(stage, path: Path) -> mujoco.MjSpec:
    """Run MuJoCo's importer on the composed stage; errors name the prim when MuJoCo does."""
    try:
        spec = mujoco.MjSpec.from_file(stage.GetRootLayer().identifier)
    except (ValueError, mujoco.FatalError) as exc:
        raise _mujoco_error(path, exc) from exc
    spec.modelname = _default_prim_name(stage)
    return spec


def _default_prim_name(stage) -> str:
    prim = stage.GetDefaultPrim()
    return prim.GetName() if prim else "World"


def usd_robot_mounts(stage) -> list[RobotMount]:
    """Prims that reference a robot described in USD (a file whose prims carry
    ``PhysicsArticulationRootAPI``), as Isaac Sim's ``add_reference_to_stage`` places one:
    the referenced file and the prim (descriptions.usd_robot reads the file)."""
    from pxr import Usd, UsdPhysics

    mounts = []
    every = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
    it = iter(Usd.PrimRange(stage.GetPseudoRoot(), every))
    for prim in it:
        asset = _referenced_file(prim)
        if asset is None or not is_usd_file(asset):
            continue
        if any(q.HasAPI(UsdPhysics.ArticulationRootAPI) for q in Usd.PrimRange(prim, every)):
            mounts.append(RobotMount(asset, str(prim.GetPath())))
            it.PruneChildren()
    return mounts


def _referenced_file(prim) -> Path | None:
    for spec in prim.GetPrimStack():
        op = spec.referenceList
        for ref in [*op.explicitItems, *op.prependedItems, *op.appendedItems, *op.addedItems]:
            if ref.assetPath:
                return Path(spec.layer.ComputeAbsolutePath(ref.assetPath))
    return None


def _set_aside_usd_robots(stage) -> list[RobotMount]:
    """Deactivate (in the in-memory root layer) the prims that reference a USD robot, so
    that MuJoCo's importer does not take their bodies into the world; the swarm world attaches
    the robots (descriptions.swarm_world)."""
    mounts = usd_robot_mounts(stage)
    for mount in mounts:
        stage.GetPrimAtPath(mount.prim).SetActive(False)
    return mounts


def stage_robots(stage, path: Path) -> list[RobotMount]:
    """The MJCF robots named on prims by ``cosim:robot:mjcf`` asset attributes, and the
    robots described in USD that prims reference (``usd_robot_mounts``)."""
    mounts = usd_robot_mounts(stage)
    for prim in stage.Traverse():
        attr = prim.GetAttribute(ROBOT_ATTR)
        if not attr or not attr.HasAuthoredValue():
            continue
        asset = attr.Get()
        resolved = getattr(asset, "resolvedPath", "") or ""
        if not resolved:
            raise WorldError(path, f"{ROBOT_ATTR} = @{getattr(asset, 'path', asset)}@ does not "
                             "resolve to a file (asset paths are relative to the layer that "
                             "authors them).", str(prim.GetPath()))
        prefix = prim.GetAttribute(PREFIX_ATTR)
        mounts.append(RobotMount(Path(resolved), str(prim.GetPath()),
                                 (prefix.Get() if prefix else "") or ""))
    return mounts


def _attach_robot(spec: mujoco.MjSpec, stage, mount: RobotMount, path: Path) -> None:
    """Attach the MJCF robot at the prim's world pose (metres, Z-up)."""
    from pxr import Gf, Usd, UsdGeom

    prim = stage.GetPrimAtPath(mount.prim)
    if not prim or not prim.IsA(UsdGeom.Xformable):
        raise WorldError(path, "a robot must be placed at an Xformable prim; none is there.",
                         mount.prim)
    try:
        robot = mujoco.MjSpec.from_file(str(mount.mjcf))
    except ValueError as exc:
        raise WorldError(path, f"robot MJCF {mount.mjcf} does not load: {_one_line(exc)}",
                         mount.prim) from exc
    pose = Gf.Transform(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(
        Usd.TimeCode.Default()))
    quat = pose.GetRotation().GetQuat()
    frame = spec.worldbody.add_frame(pos=list(pose.GetTranslation()),
                                     quat=[quat.GetReal(), *quat.GetImaginary()])
    with quiet_empty_prefix():
        spec.attach(robot, frame=frame, prefix=mount.prefix)


def add_lights(spec: mujoco.MjSpec, stage) -> None:
    """UsdLux DistantLight -> directional light, SphereLight -> point light (no shadows)."""
    from pxr import Usd, UsdGeom

    for prim in stage.Traverse():
        kind = prim.GetTypeName()
        if kind not in ("DistantLight", "SphereLight"):
            continue
        m = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default())
        light = spec.worldbody.add_light(name=str(prim.GetPath()), castshadow=False)
        light.pos = list(m.ExtractTranslation())
        if kind == "DistantLight":  # shines along its -Z axis
            light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
            light.dir = list(-np.asarray(m.TransformDir((0.0, 0.0, 1.0))))
        else:
            light.type = mujoco.mjtLightType.mjLIGHT_POINT


def _mjcf_spec(path: Path) -> mujoco.MjSpec:
    try:
        return mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:
        raise WorldError(path, f"the MJCF does not load: {_one_line(exc)}") from exc


def compile_world(spec: mujoco.MjSpec, path: Path | str) -> mujoco.MjModel:
    """Compile a world spec; a :class:`WorldError` naming the prim when MuJoCo names one."""
    try:
        with quiet_empty_prefix():
            return spec.compile()
    except (ValueError, mujoco.FatalError) as exc:
        raise _mujoco_error(Path(path), exc) from exc


@contextmanager
def quiet_empty_prefix():
    """Drop MuJoCo's 'empty prefix' warning (printed and appended to MUJOCO_LOG.TXT in the
    working directory): robots, and a swarm's groups of robots (descriptions.swarm_world), are
    attached without a prefix on purpose, to keep their names."""
    previous = mujoco.get_mju_user_warning()

    def handler(text: str) -> None:
        if "empty prefix" in text:
            return
        if previous is not None:
            previous(text)
        else:
            print(f"MuJoCo warning: {text}", file=sys.stderr)

    mujoco.set_mju_user_warning(handler)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Attaching a spec with an empty prefix")
            yield
    finally:
        mujoco.set_mju_user_warning(previous)


def _mujoco_error(path: Path, exc: Exception) -> WorldError:
    """Turn MuJoCo's 'Error: ... / Element name '/World/X'' into file, prim and reason."""
    text = str(exc)
    named = re.search(r"Element name '([^']*)'", text)
    prim = named.group(1) if named and named.group(1).startswith("/") else None
    reason = text.splitlines()[0].removeprefix("Error: ") if text else type(exc).__name__
    return WorldError(path, f"MuJoCo cannot load it: {reason}.", prim)


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split())


def _tf_reason(exc: Exception) -> str:
    """The useful part of a USD error: the quoted message (file:line:col: what was expected)."""
    quoted = re.search(r" : '(.*)'", str(exc), re.S)
    text = quoted.group(1) if quoted else str(exc)
    return " ".join(text.split()) or type(exc).__name__
