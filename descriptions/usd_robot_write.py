"""A loaded cosim robot (URDF, xacro or USD: ``descriptions.urdf.LoadedUrdf``) written as a
USD asset in the layout Isaac Sim's URDF importer writes, under the robot's own link and joint
names, so that Isaac Sim users recognise it and ``descriptions.usd_robot`` reads it back as the
same robot (``--export-usd``; docs/how-to/usd-worlds.md).

What is written, from the robot as cosim compiled it (its MuJoCo model alone) and its names:

- the robot prim (default prim, Z up, metres, kilograms) holds every link as a rigid body at
  its pose with the joints at zero (flat, not nested); ``PhysicsMassAPI`` with the mass, centre
  of mass, principal inertia and axes on every link that has mass; the geometry in
  ``visuals`` and ``collisions`` Xforms under the link (boxes, spheres, cylinders, capsules,
  meshes as ``UsdGeom.Mesh`` with their points), colours as ``displayColor``, collisions with
  ``PhysicsCollisionAPI`` (meshes as convex hulls, as MuJoCo collides them) and a physics
  material where the description gave a friction;
- joints in a ``joints`` scope, ``PhysicsRevoluteJoint`` / ``PhysicsPrismaticJoint`` /
  ``PhysicsFixedJoint`` with ``physics:body0`` the parent link, ``physics:body1`` the child and
  both local frames; limits in degrees (metres for a prismatic joint); ``physxJoint:
  maxJointVelocity`` the URDF velocity limit (degrees per second); joint damping as
  ``newton:damping`` (per degree, as Isaac Sim 6.1+ writes it);
- ``PhysicsDriveAPI:angular|linear`` on every joint cosim drives, from its actuator: a position
  servo is stiffness kp and damping kv, a velocity actuator damping kv, a motor neither (all per
  degree for a turning joint), ``maxForce`` the force limit;
- ``PhysicsArticulationRootAPI`` on the root link of a mobile robot; on the robot prim of a fixed
  one, with a fixed joint holding the base to the world (the URDF's own joint from a ``world``
  link, else Isaac's ``root_joint``);
- what USD has no schema for kept as urdf-usd-converter keeps it, ``custom`` scopes of
  ``urdf:`` attributes: the description's ``<gazebo>`` tags (sensors, friction),
  ``<ros2_control>`` and ``<transmission>`` blocks, and a Gazebo ``<sensor>`` tag for each
  sensor the scenario hung on a link.

``write_robot_usd`` returns the notes on what was not written (joint friction and armature,
extra actuators on one joint, shapes USD has no prim for).
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np

from descriptions.urdf import LoadedUrdf
from descriptions.urdf_to_mjcf import COLLISION_GROUP, VISUAL_GROUP

WORLD = "world"
KEPT_TAGS = ("gazebo", "ros2_control", "transmission")
GAZEBO_TYPES = {"lidar": "ray", "camera": "camera", "imu": "imu"}
UNITS = {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([0.0, 1.0, 0.0]),
         "Z": np.array([0.0, 0.0, 1.0])}
IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def write_robot_usd(loaded: LoadedUrdf, out: Path) -> list[str]:
    """Write ``loaded`` to ``out`` (.usda/.usdc/.usd) in Isaac Sim's importer layout; the
    notes on what was not written."""
    from pxr import Usd, UsdGeom, UsdPhysics

    model = loaded.spec.copy().compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    urdf, robot = loaded.urdf, loaded.model
    notes: list[str] = []
    name = prim_name(urdf.name or "robot")
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    top = UsdGeom.Xform.Define(stage, f"/{name}").GetPrim()
    stage.SetDefaultPrim(top)
    stage.GetRootLayer().documentation = (
        f"{urdf.name}: written by cosim --export-usd from {robot.source or 'its description'} "
        "in Isaac Sim's URDF importer layout (links as rigid bodies, joints in a joints scope, "
        "drives from cosim's actuators, limits in degrees).")

    poses = _link_poses(model, data, urdf)
    friction = _friction_materials(stage, name, model, poses)
    for link in urdf.links:
        if link == WORLD:
            continue
        if link not in poses:
            notes.append(f"link {link!r}: no body in the compiled robot, not written")
            continue
        if prim_name(link) != link:
            notes.append(f"link {link!r} is the prim {prim_name(link)!r} (USD prim names are "
                         "letters, digits and '_')")
        _write_link(stage, f"/{name}/{prim_name(link)}", link, model, poses[link], friction,
                    notes)
    UsdGeom.Scope.Define(stage, f"/{name}/joints")
    for joint in urdf.joints.values():
        _write_joint(stage, name, joint, model, poses, notes)
    if robot.mobile:
        UsdPhysics.ArticulationRootAPI.Apply(
            stage.GetPrimAtPath(f"/{name}/{prim_name(urdf.root)}"))
    else:
        UsdPhysics.ArticulationRootAPI.Apply(top)
        if urdf.root != WORLD:  # Isaac's fixed base: a fixed joint from the world
            root = UsdPhysics.FixedJoint.Define(stage, f"/{name}/root_joint")
            root.CreateBody1Rel().SetTargets([f"/{name}/{prim_name(urdf.root)}"])
    _write_kept(stage, f"/{name}/custom", _kept_elements(loaded))
    out.parent.mkdir(parents=True, exist_ok=True)
    stage.GetRootLayer().Export(str(out))
    return notes


def prim_name(text: str) -> str:
    """``text`` as a USD prim name (other characters than letters, digits and '_' as '_')."""
    clean = re.sub(r"[^A-Za-z0-9_]", "_", text)
    return clean if IDENTIFIER.match(clean) else f"_{clean}"


def _pose(pos, mat) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = np.asarray(mat, dtype=float).reshape(3, 3)
    t[:3, 3] = pos
    return t


def _link_poses(model: mujoco.MjModel, data: mujoco.MjData, urdf) -> dict[str, np.ndarray]:
    """Each link's pose relative to the robot prim: the root link's frame (the ``world``
    link's for a robot fixed by its description), joints at zero."""
    bodies = {model.body(b).name: b for b in range(1, model.nbody)}
    if urdf.root == WORLD:
        ref = np.eye(4)
    else:
        b = bodies[urdf.root]
        ref = _pose(data.xpos[b], data.xmat[b])
    inv = np.linalg.inv(ref)
    return {link: inv @ _pose(data.xpos[b], data.xmat[b]) for link, b in bodies.items()
            if link in urdf.links}


def _set_pose(xf, t: np.ndarray, scale=None, tidy: bool = False) -> None:
    """translate and orient (doubles, as the importer writes them; ``tidy``: rounded as the
    reader rounds) and an optional scale."""
    from pxr import Gf, UsdGeom

    pos, quat = t[:3, 3].tolist(), _quat(t[:3, :3])
    if tidy:  # a link's frame; a mesh's is left as MuJoCo put it (its principal axes)
        pos, quat = _tidy(pos), _tidy(quat)
    xf.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(*pos))
    xf.AddOrientOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Quatd(*quat))
    if scale is not None:
        xf.AddScaleOp().Set(Gf.Vec3f(*[float(v) for v in scale]))


def _tidy(values) -> list[float]:
    """Rounded to 12 decimals, as the reader rounds (0.5 rather than 0.5000000000000003)."""
    return [round(float(v), 12) + 0.0 for v in values]


def _quat(r: np.ndarray) -> tuple[float, float, float, float]:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(r, dtype=float).ravel())
    return tuple(float(v) for v in q)


def _quatf(r: np.ndarray):
    from pxr import Gf

    w, x, y, z = _quat(r)
    return Gf.Quatf(w, x, y, z)


def _friction_materials(stage, name: str, model: mujoco.MjModel, poses) -> dict[float, object]:
    """A physics material per friction the description gave (MuJoCo's geom priority marks
    them: cosim sets it with a Gazebo <mu1>)."""
    from pxr import UsdGeom, UsdPhysics, UsdShade

    values = sorted({float(model.geom_friction[g, 0]) for g in range(model.ngeom)
                     if model.geom_priority[g] > 0 and model.geom_group[g] == COLLISION_GROUP
                     and model.body(model.geom_bodyid[g]).name in poses})
    materials = {}
    if values:
        UsdGeom.Scope.Define(stage, f"/{name}/PhysicsMaterials")
    for mu in values:
        mat = UsdShade.Material.Define(
            stage, f"/{name}/PhysicsMaterials/{prim_name('mu_' + repr(mu))}")
        api = UsdPhysics.MaterialAPI.Apply(mat.GetPrim())
        api.CreateStaticFrictionAttr(mu)
        api.CreateDynamicFrictionAttr(mu)
        materials[mu] = mat
    return materials


def _write_link(stage, path: str, link: str, model: mujoco.MjModel, pose: np.ndarray,
                friction, notes: list[str]) -> None:
    from pxr import Gf, UsdGeom, UsdPhysics

    xf = UsdGeom.Xform.Define(stage, path)
    _set_pose(xf, pose, tidy=True)
    prim = xf.GetPrim()
    UsdPhysics.RigidBodyAPI.Apply(prim)
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, link)
    if model.body_mass[b] > 0:
        mass = UsdPhysics.MassAPI.Apply(prim)
        mass.CreateMassAttr(float(model.body_mass[b]))
        mass.CreateCenterOfMassAttr(Gf.Vec3f(*model.body_ipos[b].tolist()))
        mass.CreateDiagonalInertiaAttr(Gf.Vec3f(*model.body_inertia[b].tolist()))
        w, x, y, z = (float(v) for v in model.body_iquat[b])
        mass.CreatePrincipalAxesAttr(Gf.Quatf(w, x, y, z))
    counts = {"visuals": 0, "collisions": 0}
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != b:
            continue
        group = {COLLISION_GROUP: "collisions", VISUAL_GROUP: "visuals"}.get(
            int(model.geom_group[g]))
        if group is None:
            continue
        if counts[group] == 0:
            holder = UsdGeom.Xform.Define(stage, f"{path}/{group}")
            if group == "collisions":
                UsdGeom.Imageable(holder).CreatePurposeAttr(UsdGeom.Tokens.guide)
        where = f"{path}/{group}/{group[:-1]}_{counts[group]}"
        gprim = _write_geom(stage, where, model, g, notes)
        if gprim is None:
            continue
        counts[group] += 1
        if group == "collisions":
            _collider(gprim.GetPrim(), model, g, friction)


def _write_geom(stage, path: str, model: mujoco.MjModel, g: int, notes: list[str]):
    from pxr import Gf, UsdGeom, Vt

    kind = mujoco.mjtGeom(model.geom_type[g])
    size = model.geom_size[g]
    pose = _pose(model.geom_pos[g], np.zeros(9))
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, model.geom_quat[g])
    pose[:3, :3] = mat.reshape(3, 3)
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        gprim = UsdGeom.Cube.Define(stage, path)
        gprim.CreateSizeAttr(1.0)
        _set_pose(gprim, pose, 2 * size)
    elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        gprim = UsdGeom.Sphere.Define(stage, path)
        gprim.CreateRadiusAttr(float(size[0]))
        _set_pose(gprim, pose)
    elif kind in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
        shape = UsdGeom.Cylinder if kind == mujoco.mjtGeom.mjGEOM_CYLINDER else UsdGeom.Capsule
        gprim = shape.Define(stage, path)
        gprim.CreateRadiusAttr(float(size[0]))
        gprim.CreateHeightAttr(float(2 * size[1]))
        gprim.CreateAxisAttr(UsdGeom.Tokens.z)
        _set_pose(gprim, pose)
    elif kind == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = int(model.geom_dataid[g])
        v0, nv = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        f0, nf = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
        gprim = UsdGeom.Mesh.Define(stage, path)
        gprim.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(
            np.ascontiguousarray(model.mesh_vert[v0:v0 + nv], dtype=np.float32)))
        gprim.CreateFaceVertexCountsAttr(Vt.IntArray([3] * nf))
        gprim.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(
            np.ascontiguousarray(model.mesh_face[f0:f0 + nf].ravel(), dtype=np.int32)))
        gprim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        _set_pose(gprim, pose)
    else:
        notes.append(f"geom {model.geom(g).name!r}: a {kind.name[7:].lower()} has no USD "
                     "prim here, not written")
        return None
    matid = int(model.geom_matid[g])
    rgba = model.mat_rgba[matid] if matid >= 0 else model.geom_rgba[g]
    gprim.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*[float(v) for v in rgba[:3]])]))
    if rgba[3] < 1:
        gprim.CreateDisplayOpacityAttr(Vt.FloatArray([float(rgba[3])]))
    return gprim


def _collider(prim, model: mujoco.MjModel, g: int, friction) -> None:
    from pxr import UsdPhysics, UsdShade

    UsdPhysics.CollisionAPI.Apply(prim)
    if prim.GetTypeName() == "Mesh":
        UsdPhysics.MeshCollisionAPI.Apply(prim).CreateApproximationAttr(
            UsdPhysics.Tokens.convexHull)
    mu = float(model.geom_friction[g, 0])
    if model.geom_priority[g] > 0 and mu in friction:
        UsdShade.MaterialBindingAPI.Apply(prim).Bind(
            friction[mu], UsdShade.Tokens.weakerThanDescendants, "physics")


def _align_x(axis: np.ndarray) -> np.ndarray:
    """The rotation taking +X onto ``axis`` (a unit vector)."""
    x = np.array([1.0, 0.0, 0.0])
    v, c = np.cross(x, axis), float(x @ axis)
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([-1.0, -1.0, 1.0])
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1 + c)


def _write_joint(stage, name: str, joint, model: mujoco.MjModel, poses, notes: list[str]
                 ) -> None:
    from pxr import Gf, Sdf, UsdPhysics

    kind = joint.kind
    if kind not in ("revolute", "continuous", "prismatic", "fixed"):
        notes.append(f"joint {joint.name!r} is {kind}: written as a fixed joint (USD's "
                     "importer layout has revolute, prismatic and fixed joints)")
        kind = "fixed"
    if joint.child not in poses:
        return
    if prim_name(joint.name) != joint.name:
        notes.append(f"joint {joint.name!r} is the prim {prim_name(joint.name)!r} (USD prim "
                     "names are letters, digits and '_')")
    schema = {"fixed": UsdPhysics.FixedJoint, "prismatic": UsdPhysics.PrismaticJoint}.get(
        kind, UsdPhysics.RevoluteJoint)
    usd = schema.Define(stage, f"/{name}/joints/{prim_name(joint.name)}")
    prim = usd.GetPrim()
    if joint.parent != WORLD:
        usd.CreateBody0Rel().SetTargets([Sdf.Path(f"/{name}/{prim_name(joint.parent)}")])
    usd.CreateBody1Rel().SetTargets([Sdf.Path(f"/{name}/{prim_name(joint.child)}")])
    parent = np.eye(4) if joint.parent == WORLD else poses[joint.parent]
    rel = np.linalg.inv(parent) @ poses[joint.child]
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint.name)
    token, turn = "X", np.eye(3)
    if kind != "fixed" and j >= 0:
        axis = np.asarray(model.jnt_axis[j], dtype=float)
        token = next((t for t, u in UNITS.items() if np.allclose(axis, u, atol=1e-12)), None)
        if token is None:  # Isaac's way: the joint frame turned so that X is the axis
            token, turn = "X", _align_x(axis / np.linalg.norm(axis))
    usd.CreateLocalPos0Attr(Gf.Vec3f(*rel[:3, 3].tolist()))
    usd.CreateLocalRot0Attr(_quatf(rel[:3, :3] @ turn))
    usd.CreateLocalPos1Attr(Gf.Vec3f(0.0, 0.0, 0.0))
    usd.CreateLocalRot1Attr(_quatf(turn))
    if kind == "fixed" or j < 0:
        return
    usd.CreateAxisAttr(token)
    turning = kind != "prismatic"
    unit = math.degrees(1.0) if turning else 1.0  # USD's per-degree units
    if kind != "continuous" and joint.lower is not None and joint.upper is not None:
        usd.CreateLowerLimitAttr(joint.lower * unit)
        usd.CreateUpperLimitAttr(joint.upper * unit)
    if joint.velocity:
        prim.CreateAttribute("physxJoint:maxJointVelocity", Sdf.ValueTypeNames.Float).Set(
            joint.velocity * unit)
    dof = int(model.jnt_dofadr[j])
    if model.dof_damping[dof] > 0:
        prim.AddAppliedSchema("NewtonJointAPI")
        prim.CreateAttribute("newton:damping", Sdf.ValueTypeNames.Float).Set(
            float(model.dof_damping[dof]) / unit)
    for what, value in (("friction (frictionloss)", model.dof_frictionloss[dof]),
                        ("armature", model.dof_armature[dof])):
        if value > 0:
            notes.append(f"joint {joint.name!r}: its {what} {value:g} is not written")
    _write_drive(prim, joint.name, model, j, "angular" if turning else "linear", unit, notes)


def _write_drive(prim, joint: str, model: mujoco.MjModel, j: int, token: str, unit: float,
                 notes: list[str]) -> None:
    """The joint's actuator as a PhysicsDriveAPI (gains per degree for a turning joint)."""
    from pxr import UsdPhysics

    acts = [a for a in range(model.nu) if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
            and model.actuator_trnid[a, 0] == j]
    if not acts:
        return
    if len(acts) > 1:
        notes.append(f"joint {joint!r}: {len(acts)} actuators; the drive is the first, "
                     f"{model.actuator(acts[0]).name!r}")
    a = acts[0]
    kp, kv = -float(model.actuator_biasprm[a, 1]), -float(model.actuator_biasprm[a, 2])
    drive = UsdPhysics.DriveAPI.Apply(prim, token)
    drive.CreateTypeAttr("force")
    drive.CreateStiffnessAttr(kp / unit)
    drive.CreateDampingAttr(kv / unit)
    if model.actuator_forcelimited[a]:
        drive.CreateMaxForceAttr(float(model.actuator_forcerange[a, 1]))
    elif model.jnt_actfrclimited[j]:
        drive.CreateMaxForceAttr(float(model.jnt_actfrcrange[j, 1]))


def _kept_elements(loaded: LoadedUrdf) -> list[ET.Element]:
    """The description's <gazebo>, <ros2_control> and <transmission> elements, and a Gazebo
    sensor tag for each sensor the scenario (not the description) put on a link."""
    root = ET.fromstring(loaded.urdf_text)
    kept = [el for el in root if el.tag in KEPT_TAGS]
    described = {(s.kind, s.link) for s in loaded.urdf.sensors}
    for sensor in loaded.model.sensors:
        if (sensor.kind, sensor.link) in described:
            continue
        gazebo = ET.Element("gazebo", reference=sensor.link)
        ET.SubElement(gazebo, "sensor", type=GAZEBO_TYPES[sensor.kind], name=sensor.name)
        kept.append(gazebo)
    return kept


def _write_kept(stage, path: str, elements: list[ET.Element]) -> None:
    """urdf-usd-converter's ``custom`` scope: one Scope per element, its attributes and text
    as ``urdf:`` string attributes, the tag as the display name where the name differs."""
    from pxr import Sdf, UsdGeom

    if not elements:
        return
    UsdGeom.Scope.Define(stage, path)
    _write_children(stage, path, elements, Sdf, UsdGeom)


def _write_children(stage, path: str, elements, Sdf, UsdGeom) -> None:
    taken: dict[str, int] = {}
    for el in elements:
        base = prim_name(el.tag)
        n = taken.get(base, 0)
        taken[base] = n + 1
        prim = UsdGeom.Scope.Define(stage, f"{path}/{base if n == 0 else f'{base}_{n}'}"
                                    ).GetPrim()
        if prim.GetName() != el.tag:
            prim.SetDisplayName(el.tag)
        for key, value in el.attrib.items():
            if IDENTIFIER.match(key):
                prim.CreateAttribute(f"urdf:{key}", Sdf.ValueTypeNames.String,
                                     custom=True).Set(value)
        if el.text and el.text.strip():
            prim.CreateAttribute("urdf:text", Sdf.ValueTypeNames.String, custom=True).Set(
                el.text.strip())
        _write_children(stage, str(prim.GetPath()), list(el), Sdf, UsdGeom)
