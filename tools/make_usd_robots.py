"""Write cosim's two xacro test robots (mybot, the diff drive; myarm, the 6-joint arm) as USD
in Isaac Sim's URDF importer layout, with usd-core (pxr) alone:

- the robot prim (default prim) holds every link as a rigid body at its pose (flat, not
  nested), visuals and collisions in ``visuals`` / ``collisions`` Xforms under each link;
- joints in a ``joints`` scope: ``PhysicsRevoluteJoint`` (``physics:axis`` X, the joint frame
  turned onto the URDF axis), ``PhysicsFixedJoint``; limits in degrees;
- ``PhysicsDriveAPI:angular`` on every driven joint, gains per degree: the wheels a velocity
  drive (stiffness 0, damping 2 N m s/rad, cosim's default wheel gain), the arm's six joints
  position drives with scenarios/arm_urdf.yaml's gains; ``maxForce`` the URDF effort;
- ``PhysicsArticulationRootAPI`` on the mobile robot's root link; for the arm on the robot
  prim, with a ``root_joint`` holding base_link to the world (Isaac's fixed base);
- Gazebo friction (``<mu1>``) as physics materials bound to the collisions; mybot's camera as
  a ``UsdGeom.Camera`` under camera_link; massless links rigid bodies without mass.

What Isaac's layout has no place for is left out: joint damping (``<dynamics>``) and the
Gazebo sensor tags (cosim's scenario names the lidar and IMU links instead).

    .venv/bin/python tools/make_usd_robots.py   # writes scenarios/robots/usd/*_isaac.usda

With ``--converter EXE`` (urdf-usd-converter's command, PyPI ``urdf-usd-converter==0.3.4``,
installed apart: ``python -m venv /tmp/uuc && /tmp/uuc/bin/pip install
urdf-usd-converter==0.3.4``) it also converts both expanded xacros with it and writes each
result flattened into one layer, ``*_urdf_usd_converter.usda`` (urdf-usd-converter's layout).
With ``--mujoco-converter EXE`` (PyPI ``mujoco-usd-converter==0.8.0``, installed apart the same
way) it converts the MJCF cosim makes of each robot (descriptions.urdf.load_urdf with the
settings of scenarios/nav_urdf.yaml and arm_urdf.yaml: its actuators become ``MjcActuator``
prims) and writes ``*_mujoco_usd_converter.usda``.
"""

from __future__ import annotations

import argparse
import math
import struct
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from descriptions.packages import PackageResolver  # noqa: E402
from descriptions.urdf_parse import Urdf, parse_urdf  # noqa: E402
from descriptions.xacro_expand import expand  # noqa: E402

OUT = ROOT / "scenarios" / "robots" / "usd"
WHEEL_KV = 2.0  # cosim's default wheel gain (descriptions/urdf.py DEFAULT_GAINS)
ARM_GAINS = {"shoulder_pan": (200, 20), "shoulder_lift": (200, 20), "elbow": (200, 20),
             "wrist_1": (30, 2), "wrist_2": (30, 2), "wrist_3": (30, 2)}  # arm_urdf.yaml
PER_DEGREE = math.pi / 180


def rpy_matrix(r: float, p: float, y: float) -> np.ndarray:
    """URDF's rpy: Rz(y) Ry(p) Rx(r)."""
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), \
        math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def origin(el: ET.Element | None) -> np.ndarray:
    """An ``<origin>`` as a 4x4 transform."""
    t = np.eye(4)
    o = None if el is None else el.find("origin")
    if o is not None:
        t[:3, 3] = [float(v) for v in o.get("xyz", "0 0 0").split()]
        t[:3, :3] = rpy_matrix(*(float(v) for v in o.get("rpy", "0 0 0").split()))
    return t


def quat(r: np.ndarray):
    """A rotation matrix as Gf.Quatf (w, x, y, z)."""
    from pxr import Gf

    q = Gf.Matrix3d(*r.T.ravel().tolist()).ExtractRotation().GetQuat()
    return Gf.Quatf(q.GetReal(), Gf.Vec3f(q.GetImaginary()))


def align_x(axis) -> np.ndarray:
    """The rotation taking +X onto ``axis``."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    x = np.array([1.0, 0.0, 0.0])
    v, c = np.cross(x, a), float(x @ a)
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([-1.0, -1.0, 1.0])
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1 + c)


def read_mesh(path: Path) -> tuple[list, list]:
    """(vertices, triangles) of a binary STL or an OBJ."""
    if path.suffix.lower() == ".obj":
        verts, faces = [], []
        for line in path.read_text().splitlines():
            parts = line.split()
            if parts[:1] == ["v"]:
                verts.append([float(v) for v in parts[1:4]])
            elif parts[:1] == ["f"]:
                idx = [int(p.split("/")[0]) - 1 for p in parts[1:]]
                faces += [(idx[0], idx[i], idx[i + 1]) for i in range(1, len(idx) - 1)]
        return verts, faces
    data = path.read_bytes()
    (n,) = struct.unpack_from("<I", data, 80)
    tri = np.frombuffer(data, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")],
                        count=n, offset=84)["v"].reshape(-1, 3)
    unique, inverse = np.unique(tri, axis=0, return_inverse=True)
    return unique.tolist(), inverse.reshape(-1, 3).tolist()


def set_pose(xf, t: np.ndarray, scale=None) -> None:
    """Author translate, orient (and scale) ops on an Xformable."""
    from pxr import Gf

    xf.AddTranslateOp().Set(Gf.Vec3d(*t[:3, 3].tolist()))
    xf.AddOrientOp().Set(quat(t[:3, :3]))
    if scale is not None:
        xf.AddScaleOp().Set(Gf.Vec3f(*scale))


def write_robot(urdf: Urdf, text: str, resolver: PackageResolver, out: Path, fixed: bool,
                drives: dict[str, tuple[float, float]], camera_link: str | None) -> None:
    """The robot in Isaac's importer layout at ``out``."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdShade, Vt

    xml = ET.fromstring(text)
    colours = {m.get("name"): m.find("color").get("rgba") for m in xml.findall("material")
               if m.find("color") is not None}
    stage = Usd.Stage.CreateNew(str(out))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    robot = UsdGeom.Xform.Define(stage, f"/{urdf.name}").GetPrim()
    stage.SetDefaultPrim(robot)
    stage.GetRootLayer().documentation = (
        f"{urdf.name}: cosim's xacro test robot in Isaac Sim's URDF importer layout, written "
        "by tools/make_usd_robots.py from the xacro (do not edit by hand).")
    pose = {urdf.root: np.eye(4)}
    order = [urdf.root]
    for name in order:
        for j in urdf.children(name):
            pose[j.child] = pose[name] @ origin(xml.find(f"joint[@name='{j.name}']"))
            order.append(j.child)
    materials = {}
    for mu in sorted(set(urdf.friction.values())):
        mat = UsdShade.Material.Define(stage, f"/{urdf.name}/PhysicsMaterials/"
                                              f"mu_{str(mu).replace('.', '_')}")
        api = UsdPhysics.MaterialAPI.Apply(mat.GetPrim())
        api.CreateStaticFrictionAttr(mu)
        api.CreateDynamicFrictionAttr(mu)
        materials[mu] = mat
    for name in order:
        link = urdf.links[name]
        path = f"/{urdf.name}/{name}"
        xf = UsdGeom.Xform.Define(stage, path)
        set_pose(xf, pose[name])
        prim = xf.GetPrim()
        UsdPhysics.RigidBodyAPI.Apply(prim)
        if link.mass:
            el = xml.find(f"link[@name='{name}']/inertial")
            mass = UsdPhysics.MassAPI.Apply(prim)
            mass.CreateMassAttr(link.mass)
            o = origin(el)
            mass.CreateCenterOfMassAttr(Gf.Vec3f(*o[:3, 3].tolist()))
            mass.CreateDiagonalInertiaAttr(Gf.Vec3f(*link.inertia))
            mass.CreatePrincipalAxesAttr(quat(o[:3, :3]))
        for role, elements in (("visuals", link.visuals), ("collisions", link.collisions)):
            if not elements:
                continue
            group = UsdGeom.Xform.Define(stage, f"{path}/{role}")
            if role == "collisions":
                UsdGeom.Imageable(group).CreatePurposeAttr(UsdGeom.Tokens.guide)
            for i, el in enumerate(elements):
                geom = _shape(stage, f"{path}/{role}/{role[:-1]}_{i}", el, resolver, link, xml)
                if geom is None:
                    continue
                g = geom.GetPrim()
                material = el.find("material")
                rgba = None if material is None else (
                    material.find("color").get("rgba") if material.find("color") is not None
                    else colours.get(material.get("name")))
                if rgba:
                    UsdGeom.Gprim(g).CreateDisplayColorAttr(
                        Vt.Vec3fArray([Gf.Vec3f(*[float(v) for v in rgba.split()[:3]])]))
                if role == "collisions":
                    UsdPhysics.CollisionAPI.Apply(g)
                    if g.GetTypeName() == "Mesh":
                        UsdPhysics.MeshCollisionAPI.Apply(g).CreateApproximationAttr(
                            UsdPhysics.Tokens.convexHull)
                    if name in urdf.friction:
                        UsdShade.MaterialBindingAPI.Apply(g).Bind(
                            materials[urdf.friction[name]], UsdShade.Tokens.weakerThanDescendants,
                            "physics")
    if camera_link:
        cam = UsdGeom.Camera.Define(stage, f"/{urdf.name}/{camera_link}/camera")
        look = np.eye(4)  # the camera's -Z along the link's +X, its +Y along the link's +Z
        look[:3, :3] = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        set_pose(cam, look)
        cam.CreateFocalLengthAttr(1.0)
        cam.CreateHorizontalApertureAttr(2 * math.tan(1.047 / 2))
        cam.CreateVerticalApertureAttr(2 * math.tan(1.047 / 2) * 120 / 160)
        cam.CreateClippingRangeAttr(Gf.Vec2f(0.05, 10.0))
    UsdGeom.Scope.Define(stage, f"/{urdf.name}/joints")
    for j in urdf.joints.values():
        kind = {"fixed": "Fixed", "prismatic": "Prismatic"}.get(j.kind, "Revolute")
        joint = getattr(UsdPhysics, f"{kind}Joint").Define(
            stage, f"/{urdf.name}/joints/{j.name}")
        joint.CreateBody0Rel().SetTargets([Sdf.Path(f"/{urdf.name}/{j.parent}")])
        joint.CreateBody1Rel().SetTargets([Sdf.Path(f"/{urdf.name}/{j.child}")])
        o = origin(xml.find(f"joint[@name='{j.name}']"))
        turn = np.eye(3) if j.kind == "fixed" else align_x(j.axis)
        joint.CreateLocalPos0Attr(Gf.Vec3f(*o[:3, 3].tolist()))
        joint.CreateLocalRot0Attr(quat(o[:3, :3] @ turn))
        joint.CreateLocalPos1Attr(Gf.Vec3f(0, 0, 0))
        joint.CreateLocalRot1Attr(quat(turn))
        if j.kind == "fixed":
            continue
        joint.CreateAxisAttr("X")
        if j.kind == "revolute":
            joint.CreateLowerLimitAttr(math.degrees(j.lower))
            joint.CreateUpperLimitAttr(math.degrees(j.upper))
        if j.name in drives:
            kp, kv = drives[j.name]
            drive = UsdPhysics.DriveAPI.Apply(joint.GetPrim(), "angular")
            drive.CreateTypeAttr("force")
            drive.CreateStiffnessAttr(kp * PER_DEGREE)
            drive.CreateDampingAttr(kv * PER_DEGREE)
            if j.effort:
                drive.CreateMaxForceAttr(j.effort)
        if j.velocity:
            joint.GetPrim().CreateAttribute("physxJoint:maxJointVelocity",
                                            Sdf.ValueTypeNames.Float).Set(
                math.degrees(j.velocity))
    if fixed:
        UsdPhysics.ArticulationRootAPI.Apply(robot)
        root = UsdPhysics.FixedJoint.Define(stage, f"/{urdf.name}/root_joint")
        root.CreateBody1Rel().SetTargets([Sdf.Path(f"/{urdf.name}/{urdf.root}")])
    else:
        UsdPhysics.ArticulationRootAPI.Apply(stage.GetPrimAtPath(f"/{urdf.name}/{urdf.root}"))
    stage.GetRootLayer().Save()


def _shape(stage, path: str, el: ET.Element, resolver: PackageResolver, link, xml):
    from pxr import Gf, UsdGeom, Vt

    geometry = el.find("geometry")
    shape = geometry[0]
    t = origin(el)
    if shape.tag == "box":
        cube = UsdGeom.Cube.Define(stage, path)
        cube.CreateSizeAttr(1.0)
        set_pose(cube, t, [float(v) for v in shape.get("size").split()])
        return cube
    if shape.tag == "sphere":
        sphere = UsdGeom.Sphere.Define(stage, path)
        sphere.CreateRadiusAttr(float(shape.get("radius")))
        set_pose(sphere, t)
        return sphere
    if shape.tag == "cylinder":
        cyl = UsdGeom.Cylinder.Define(stage, path)
        cyl.CreateRadiusAttr(float(shape.get("radius")))
        cyl.CreateHeightAttr(float(shape.get("length")))
        cyl.CreateAxisAttr("Z")
        set_pose(cyl, t)
        return cyl
    file = resolver.resolve_uri(shape.get("filename"), Path("."))
    if file.suffix.lower() == ".dae":  # drawn as the collision mesh, as cosim draws it
        file = resolver.resolve_uri(link.collisions[0].find("geometry/mesh").get("filename"),
                                    Path("."))
    verts, faces = read_mesh(file)
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*v) for v in verts]))
    mesh.CreateFaceVertexCountsAttr([3] * len(faces))
    mesh.CreateFaceVertexIndicesAttr([i for f in faces for i in f])
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    scale = shape.get("scale")
    set_pose(mesh, t, None if scale is None else [float(v) for v in scale.split()])
    return mesh


def convert(exe: str, name: str, text: str, package: Path) -> None:
    """Convert the expanded URDF with urdf-usd-converter and flatten its layers into one."""
    from pxr import Usd

    with tempfile.TemporaryDirectory() as tmp:
        urdf = Path(tmp) / f"{name}.urdf"
        urdf.write_text(text)
        subprocess.run([exe, str(urdf), str(Path(tmp) / "out"), "--package",
                        f"{name}_description={package}"], check=True, capture_output=True)
        flat = Usd.Stage.Open(str(Path(tmp) / "out" / f"{name}.usda")).Flatten()
        flat.documentation = (f"{name} converted by urdf-usd-converter 0.3.4 from cosim's "
                              "xacro test robot, flattened into one layer by "
                              "tools/make_usd_robots.py --converter (do not edit by hand).")
        out = OUT / f"{name}_urdf_usd_converter.usda"
        flat.Export(str(out))
        print(f"wrote {out.relative_to(ROOT)}")


MJCF_OPTIONS = {
    "mybot": {"wheels": ("wheel_left_joint", "wheel_right_joint")},
    "myarm": {"base": "fixed", "interfaces": {"wrist_2": "position", "wrist_3": "position"},
              "gains": {"position": {"kp": 200, "kv": 20}, "wrist_1": {"kp": 30, "kv": 2},
                        "wrist_2": {"kp": 30, "kv": 2}, "wrist_3": {"kp": 30, "kv": 2}}}}


def convert_mjcf(exe: str, name: str, package: Path) -> None:
    """cosim's MJCF of the robot converted by mujoco-usd-converter, flattened into one layer."""
    from pxr import Usd

    from descriptions.urdf import UrdfOptions, load_urdf

    loaded = load_urdf(package / "urdf" / f"{name}.urdf.xacro", UrdfOptions(
        packages={f"{name}_description": str(package)}, **MJCF_OPTIONS[name]))
    with tempfile.TemporaryDirectory() as tmp:
        mjcf = Path(tmp) / f"{name}.xml"
        mjcf.write_text(loaded.spec.to_xml())
        subprocess.run([exe, str(mjcf), str(Path(tmp) / "out")], check=True,
                       capture_output=True)
        flat = Usd.Stage.Open(str(Path(tmp) / "out" / f"{name}.usda")).Flatten()
        flat.documentation = (f"{name} as cosim compiles it (MJCF) converted by "
                              "mujoco-usd-converter 0.8.0, flattened into one layer by "
                              "tools/make_usd_robots.py --mujoco-converter (do not edit).")
        out = OUT / f"{name}_mujoco_usd_converter.usda"
        flat.Export(str(out))
        print(f"wrote {out.relative_to(ROOT)}")


def main() -> None:
    """Write both robots."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--converter", help="urdf-usd-converter's command: convert with it too")
    p.add_argument("--mujoco-converter", help="mujoco-usd-converter's command: convert "
                   "cosim's MJCF of each robot with it too")
    ns = p.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    for name, fixed, drives, camera in (
            ("mybot", False, {"wheel_left_joint": (0.0, WHEEL_KV),
                              "wheel_right_joint": (0.0, WHEEL_KV)}, "camera_link"),
            ("myarm", True, ARM_GAINS, None)):
        package = ROOT / "scenarios" / "robots" / f"{name}_description"
        resolver = PackageResolver({f"{name}_description": str(package)}, {})
        text = expand(package / "urdf" / f"{name}.urdf.xacro", {}, resolver).urdf
        out = OUT / f"{name}_isaac.usda"
        out.unlink(missing_ok=True)
        write_robot(parse_urdf(text, name), text, resolver, out, fixed, drives, camera)
        print(f"wrote {out.relative_to(ROOT)}")
        if ns.converter:
            convert(ns.converter, name, text, package)
        if ns.mujoco_converter:
            convert_mjcf(ns.mujoco_converter, name, package)


if __name__ == "__main__":
    main()
