"""A robot described in OpenUSD loaded as a cosim robot, the same thing a URDF robot is
(``descriptions.urdf.LoadedUrdf``: the MjSpec with cosim's actuators and sensors, the
robot model, ``/robot_description``), so nothing after the load knows USD.

``load_usd(path, options)`` reads the stage (``descriptions.usd_stage_robot``: links,
joints, drives, geometry, cameras, frames; names are the prims' names), writes it as the
URDF it is equivalent to (meshes as binary STL beside it in a cache folder keyed by their
content) and loads that through ``descriptions.urdf.load_urdf``, with the drives as the
actuators' settings:

- a ``PhysicsDriveAPI`` with stiffness > 0 is a position servo (kp = stiffness, kv =
  damping, both per radian), with stiffness 0 and damping > 0 a velocity servo (kv =
  damping), with neither a motor (effort); ``maxForce`` is the force limit; the scenario's
  ``robots.usd.interfaces`` and ``gains`` override them;
- a joint without a drive is commanded only when the scenario's interfaces, or the
  ``<ros2_control>`` block urdf-usd-converter keeps as ``urdf:`` scopes, name it (as a URDF
  joint outside ``<ros2_control>``); a drive wheel gets a velocity actuator either way;
- the base is free or fixed as the scenario says; ``auto``: fixed when a joint holds the
  robot to the world (Isaac's ``root_joint``), else free (a mobile robot);
- a ``UsdGeom.Camera`` is a camera on a frame of its own name; lidar and IMU hang on a
  link or frame the scenario names (``robots.usd.sensors``) or a kept Gazebo tag names.

What USD says that this does not keep is listed in the robot's notes (one warning line at
load).
"""

from __future__ import annotations

import hashlib
import math
import struct
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from descriptions.description_error import DescriptionError
from descriptions.mesh_convert import cache_dir, write_atomic
from descriptions.urdf import LoadedUrdf, UrdfOptions, load_urdf
from descriptions.usd_geometry import Geom
from descriptions.usd_joints import WORLD
from descriptions.usd_stage_robot import Link, StageRobot, read_stage_robot
from plan.errors import WorldError

BODY_CAMERA = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])  # x fwd, z up
OPTICAL_CAMERA = np.diag([1.0, -1.0, -1.0])  # z forward, y down (REP-103)


def load_usd(path: Path | str, options: UrdfOptions | None = None) -> LoadedUrdf:
    """Read, convert and describe the USD robot ``path``; DescriptionError on anything
    wrong (naming the prim)."""
    from descriptions.worldfile import open_stage

    options = options or UrdfOptions()
    path = Path(path).resolve()
    try:
        stage = open_stage(path)
    except WorldError as exc:
        raise DescriptionError(str(path), str(exc).split(": ", 1)[-1],
                               fix="a USD file that usd-core opens") from None
    robot = read_stage_robot(stage, str(path))
    notes = list(robot.notes)
    base = options.base
    world = robot.world_joint
    if base == "auto":
        base = "fixed" if world is not None else "free"
    if base == "free" and world is not None:
        notes.append(f"joint {world.name!r} holds the robot to the world; the base is free, "
                     "so it is dropped")
        robot.joints.pop(world.name)
    interfaces, gains = _commands(robot, options, str(path))
    _check_masses(robot, str(path), base == "free")
    urdf_text, folder = write_urdf(robot, notes)
    loaded = load_urdf(folder / "robot.urdf", replace(
        options, base=base, interfaces=interfaces, gains=gains, args={}, packages={}))
    notes += [n for n in loaded.notes if n not in notes]
    model = replace(loaded.model, source=str(path), reader="usd", notes=tuple(notes))
    return LoadedUrdf(urdf_text, loaded.spec, loaded.urdf, model, notes)


def _commands(robot: StageRobot, options: UrdfOptions, description: str
              ) -> tuple[dict[str, str], dict[str, dict[str, float]]]:
    """The command interface and gains of every driven joint: its drive, over-ridden by the
    scenario's; DescriptionError for a joint something drives that has neither."""
    wheels = set(options.wheels or ())
    controlled = {j.get("name") for el in robot.kept if el.tag == "ros2_control"
                  for j in el.findall("joint")}
    interfaces: dict[str, str] = {}
    gains: dict[str, dict[str, float]] = {k: dict(v) for k, v in options.gains.items()}
    for joint in robot.joints.values():
        drive = joint.drive
        if drive is None or joint.kind == "fixed":
            continue
        if joint.name in wheels:
            drive_gains = {"kv": drive.damping} if drive.damping > 0 else {}
        elif drive.stiffness > 0:
            interfaces[joint.name] = "position"
            drive_gains = {"kp": drive.stiffness, "kv": drive.damping}
        elif drive.damping > 0:
            interfaces[joint.name] = "velocity"
            drive_gains = {"kv": drive.damping}
        else:
            interfaces[joint.name] = "effort"
            drive_gains = {}
        gains[joint.name] = {**drive_gains, **gains.get(joint.name, {})}
    for name, interface in options.interfaces.items():
        if name not in robot.joints:
            raise DescriptionError(description, "robots.usd.interfaces names a joint the "
                                   "robot has not", joint=name,
                                   fix=f"one of its joint prims: {list(robot.joints)}")
        interfaces[name] = interface
    driven = {j.get("name") for el in robot.kept if el.tag == "transmission"
              for j in el.findall("joint")}
    driven |= {k for k in options.gains if k in robot.joints}
    for name in sorted(driven - set(interfaces) - controlled - wheels):
        joint = robot.joints.get(name)
        raise DescriptionError(description, "the joint is driven (a transmission or gains "
                               "name it) but has neither a PhysicsDriveAPI nor a command "
                               "interface", joint=name, prim=None if joint is None else
                               joint.prim, fix=f"add robots.usd.interfaces: {{{name}: position}}"
                               " (or velocity, effort), or a PhysicsDriveAPI on the joint")
    return interfaces, gains


def _check_masses(robot: StageRobot, description: str, free: bool) -> None:
    def welded(link: str) -> float:
        return (robot.links[link].mass or 0.0) + sum(
            welded(j.child) for j in robot.joints.values()
            if j.parent == link and j.kind == "fixed")

    moving = [(j.child, j) for j in robot.joints.values() if j.kind != "fixed"]
    if free:
        moving.append((robot.root, None))
    for link, joint in moving:
        if welded(link) <= 1e-6:
            moved = f"joint {joint.name!r} moves it" if joint else "it is the mobile root"
            raise DescriptionError(description, f"link {link!r} has no mass and {moved}",
                                   prim=robot.links[link].prim,
                                   fix="apply PhysicsMassAPI with physics:mass > 0 and "
                                       "physics:diagonalInertia to the link (a mass from "
                                       "density is not computed)")


def _frame_poses(robot: StageRobot, notes: list[str]) -> dict[str, np.ndarray]:
    """Each link's frame relative to the robot prim: its prim's pose, moved to the joint's
    pivot where a moving joint turns it about another point (URDF's joint frame is the child
    link's), turned to a camera convention for a camera."""
    top = np.linalg.inv(robot.pose)
    frames = {}
    for name, link in robot.links.items():
        frame = top @ link.pose
        joint = next((j for j in robot.joints.values() if j.child == name), None)
        if joint is not None and joint.kind != "fixed" and np.linalg.norm(joint.pivot) > 1e-9:
            frame = frame.copy()
            frame[:3, 3] = frame[:3, :3] @ np.array(joint.pivot) + frame[:3, 3]
            notes.append(f"link {name!r}: its frame is put at joint {joint.name!r}'s pivot "
                         f"{tuple(round(v, 6) for v in joint.pivot)} (a URDF joint turns its "
                         "child about the child's frame)")
        if link.camera is not None:
            frame = frame.copy()
            frame[:3, :3] = frame[:3, :3] @ (OPTICAL_CAMERA if "optical" in name
                                             else BODY_CAMERA)
        frames[name] = frame
    return frames


def _xyz_rpy(t: np.ndarray) -> dict[str, str]:
    r = t[:3, :3]
    roll = math.atan2(r[2, 1], r[2, 2])
    pitch = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    yaw = math.atan2(r[1, 0], r[0, 0])
    return {"xyz": " ".join(_num(v) for v in t[:3, 3]),
            "rpy": " ".join(_angle(v) for v in (roll, pitch, yaw))}


def _angle(v: float) -> str:
    """An angle of the URDF text: a multiple of 90 degrees (within 1e-9 rad, as USD's
    float32 leaves one) exactly, so that a wheel turned on its side stays square to the
    floor; any other to 12 significant digits (``_num``)."""
    quarters = round(v / (math.pi / 2))
    if abs(v - quarters * (math.pi / 2)) < 1e-9:
        return "0" if quarters == 0 else repr(quarters * (math.pi / 2))
    return _num(v)


def _num(v: float) -> str:
    """A number of the URDF text, to 12 significant digits: far below the float32 tilt that
    usd_prims.snapped removes, and above the last bits by which matrix products and
    decompositions (BLAS, LAPACK) differ between CPUs: the text is in /robot_description,
    so in the digest."""
    v = float(v)
    return "0" if abs(v) < 1e-12 else repr(float(f"{v:.12g}"))


def write_urdf(robot: StageRobot, notes: list[str]) -> tuple[str, Path]:
    """The robot as URDF text, written with its meshes (binary STL, named relative to it, so
    the text and /robot_description hold no machine's path) to a cache folder named by the
    content (every process writes, or finds, the same files); (text, folder)."""
    frames = _frame_poses(robot, notes)
    root = ET.Element("robot", name=robot.name)
    meshes: dict[str, bytes] = {}
    if robot.world_joint is not None:
        ET.SubElement(root, "link", name=WORLD)
    frictions: dict[str, float] = {}
    for name, link in robot.links.items():
        el = ET.SubElement(root, "link", name=name)
        frame = frames[name]
        if link.mass is not None:
            _inertial(el, link, frame)
        counts = {"visual": 0, "collision": 0}
        for geom in link.geoms:
            _geom(el, geom, frame, meshes, f"{name}_{geom.role}_{counts[geom.role]}")
            counts[geom.role] += 1
            if geom.role == "collision" and geom.friction is not None:
                frictions[name] = min(frictions.get(name, geom.friction), geom.friction)
    for joint in robot.joints.values():
        el = ET.SubElement(root, "joint", name=joint.name,
                           type="continuous" if joint.kind == "revolute" and (
                               joint.lower is None or joint.upper is None) else joint.kind)
        ET.SubElement(el, "parent", link=joint.parent)
        ET.SubElement(el, "child", link=joint.child)
        parent = np.eye(4) if joint.parent == WORLD else frames[joint.parent]
        ET.SubElement(el, "origin", _xyz_rpy(np.linalg.inv(parent) @ frames[joint.child]))
        if joint.kind == "fixed":
            continue
        ET.SubElement(el, "axis", xyz=" ".join(_num(v) for v in joint.axis))
        limit = {k: _num(v) for k, v in (("lower", joint.lower), ("upper", joint.upper),
                                         ("effort", joint.effort),
                                         ("velocity", joint.velocity)) if v is not None}
        if limit:
            ET.SubElement(el, "limit", limit)
        if joint.damping:
            ET.SubElement(el, "dynamics", damping=_num(joint.damping))
    gazebo_links = {el.get("reference") for el in robot.kept if el.tag == "gazebo"}
    for name, mu in frictions.items():
        if name not in gazebo_links:
            g = ET.SubElement(root, "gazebo", reference=name)
            ET.SubElement(g, "mu1").text = _num(mu)
            ET.SubElement(g, "mu2").text = _num(mu)
    for link in robot.links.values():
        if link.camera is not None:
            g = ET.SubElement(root, "gazebo", reference=link.name)
            s = ET.SubElement(g, "sensor", type="camera", name=link.name)
            cam = ET.SubElement(s, "camera")
            ET.SubElement(cam, "horizontal_fov").text = _num(link.camera.horizontal_fov)
            clip = ET.SubElement(cam, "clip")
            ET.SubElement(clip, "near").text = _num(link.camera.clip[0])
            ET.SubElement(clip, "far").text = _num(link.camera.clip[1])
    for el in robot.kept:
        root.append(el)
    ET.indent(root)
    digest = hashlib.sha256()
    for key in sorted(meshes):
        digest.update(key.encode() + meshes[key])
    text = ET.tostring(root, encoding="unicode")
    digest.update(text.encode())
    folder = cache_dir("usd-robots") / digest.hexdigest()[:20]
    for name, data in meshes.items():
        _write(folder / name, data)
    _write(folder / "robot.urdf", text.encode())
    return text, folder


def _write(path: Path, data: bytes) -> None:
    if path.is_file() and path.read_bytes() == data:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, data)


def _inertial(el: ET.Element, link: Link, frame: np.ndarray) -> None:
    from descriptions.usd_prims import quat_matrix

    inertial = ET.SubElement(el, "inertial")
    local = np.linalg.inv(frame) @ link.pose
    com = np.eye(4)
    com[:3, :3] = local[:3, :3] @ quat_matrix(*link.principal)
    com[:3, 3] = local[:3, :3] @ np.array(link.com) + local[:3, 3]
    ET.SubElement(inertial, "origin", _xyz_rpy(com))
    ET.SubElement(inertial, "mass", value=_num(link.mass))
    ixx, iyy, izz = link.inertia or (0.0, 0.0, 0.0)
    ET.SubElement(inertial, "inertia", ixx=_num(ixx), iyy=_num(iyy), izz=_num(izz),
                  ixy="0", ixz="0", iyz="0")


def _geom(el: ET.Element, geom: Geom, frame: np.ndarray, meshes: dict[str, bytes],
          name: str) -> None:
    g = ET.SubElement(el, geom.role, name=name)
    ET.SubElement(g, "origin", _xyz_rpy(np.linalg.inv(frame) @ geom.pose))
    shape = ET.SubElement(g, "geometry")
    if geom.kind == "box":
        ET.SubElement(shape, "box", size=" ".join(_num(v) for v in geom.size))
    elif geom.kind == "sphere":
        ET.SubElement(shape, "sphere", radius=_num(geom.size[0]))
    elif geom.kind in ("cylinder", "capsule"):
        ET.SubElement(shape, geom.kind, radius=_num(geom.size[0]), length=_num(geom.size[1]))
    else:
        data = stl_bytes(geom.vertices, geom.faces)
        file = f"{hashlib.sha256(data).hexdigest()[:20]}.stl"
        meshes[file] = data
        ET.SubElement(shape, "mesh", filename=file)  # beside robot.urdf: no machine's path
    if geom.role == "visual" and geom.rgba is not None:
        material = ET.SubElement(g, "material", name=f"{name}_colour")
        ET.SubElement(material, "color", rgba=" ".join(_num(v) for v in geom.rgba))


def stl_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A binary STL of triangles ``faces`` (indices into ``vertices``)."""
    tri = vertices[faces].astype(np.float32)
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = (normals / np.where(lengths > 0, lengths, 1)).astype(np.float32)
    record = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    record["n"], record["v"] = normals, tri
    return b"cosim usd mesh".ljust(80, b" ") + struct.pack("<I", len(tri)) + record.tobytes()


def usd_options(settings: Mapping) -> UrdfOptions:
    """UrdfOptions (the drive, sensors, interfaces and gains) from a scenario's
    ``robots.usd`` settings (``plan.description_spec.UsdSpec`` as a dict)."""
    gains = {k: {g: v for g, v in s.items() if v is not None}
             for k, s in (settings.get("gains") or {}).items()}
    wheels = settings.get("wheels")
    return UrdfOptions(base=settings.get("base", "auto"),
                       wheels=None if wheels is None else tuple(wheels),
                       wheel_radius=settings.get("wheel_radius"),
                       wheel_separation=settings.get("wheel_separation"),
                       sensors=dict(settings.get("sensors") or {}),
                       interfaces=dict(settings.get("interfaces") or {}), gains=gains)


_CACHE: dict[tuple[str, str, int, int], LoadedUrdf] = {}


def section_options(section: dict | None, scenario_dir: Path) -> UrdfOptions:
    """UrdfOptions from a scenario's ``robots.usd`` section as read from its YAML
    (cosim-describe), by the run's way: the settings JSON its layout carries, read back."""
    import json

    from plan.description_spec import UsdSpec

    settings = layout_settings(UsdSpec.model_validate(section or {}), scenario_dir)
    return usd_options(json.loads(settings))


def layout_settings(spec, scenario_dir: Path) -> str:
    """A scenario's ``robots.usd`` settings (plan.description_spec.UsdSpec; None: the
    defaults) as the swarm layout carries them: JSON (nothing in them is a path)."""
    from plan.description_spec import UsdSpec

    return (spec or UsdSpec()).model_dump_json()


def layout_usd_robot(description: Path | str, settings: str) -> LoadedUrdf:
    """The robot of a swarm layout whose description is USD (``settings``: the
    ``robots.usd`` JSON), loaded once per process."""
    import json

    path = Path(description).resolve()
    stat = path.stat()  # an edited file is read again (a notebook, the run API)
    key = (str(path), settings, stat.st_mtime_ns, stat.st_size)
    if key not in _CACHE:
        loaded = load_usd(description, usd_options(json.loads(settings or "{}")))
        _CACHE[key] = replace(loaded, model=replace(loaded.model, settings=settings))
    return _CACHE[key]
