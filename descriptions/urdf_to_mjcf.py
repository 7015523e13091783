"""A URDF converted to a MuJoCo MjSpec, faithfully, saying what it changed.

MuJoCo's own URDF compiler does the geometry (origins, rpy, axes, inertia frames), told
not to lose anything: ``fusestatic="false"`` keeps every fixed-joint link as a body of its
own, ``discardvisual="false"`` keeps the visuals, ``inertiafromgeom="false"`` keeps the
masses the URDF gives (none invented from geometry). Before it reads the document here:

- every mesh URI (``package://``, ``file://``, relative) becomes an absolute path, and a
  missing package or file is a DescriptionError naming the link and the path tried;
- an ASCII STL or COLLADA (``.dae``) mesh, which MuJoCo cannot read, is converted to binary
  STL (descriptions/mesh_convert.py; a COLLADA visual keeps its colours, one geom per
  colour); a visual that does not convert, or in another format MuJoCo cannot read, is
  replaced by the link's collision geometry (a note says so), such a collision mesh is an
  error;
- a moving link (the child of a non-fixed joint, or the root of a mobile robot) whose
  welded mass is zero is an error naming the link and the fix.

After it: geoms are named (``LINK_collision_0``, ``LINK_visual_0``), collision geoms go to
geom group 3 and visuals to group 4 (so cosim's lidar and cameras, which see groups 0-2, do
not see the robot itself, as with cosim's own robot), Gazebo ``<mu1>`` becomes the geom's
sliding friction, every link gets a site of its own name at its frame (sensor and footprint
frames never vanish), a mobile robot's root link a free joint, and every two links a joint
connects a contact exclusion (adjacent links never collide; other pairs do). A root link
named ``world`` (UR and Franka descriptions) is MuJoCo's world body, not a body of the robot:
the link it holds is fixed where the robot is placed, and its frame is a site ``world``
there.
"""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import mujoco

from descriptions.description_error import DescriptionError
from descriptions.mesh_convert import MeshError, MeshPart, mujoco_meshes
from descriptions.packages import PackageNotFound, PackageResolver
from descriptions.urdf_parse import Urdf

MESH_FORMATS = (".stl", ".obj", ".msh")
COLLISION_GROUP = 3
VISUAL_GROUP = 4
SITE_GROUP = 5
MIN_MASS = 1e-6
WORLD_SITE = "world"  # the frame of a root link named 'world' (a fixed arm's placement)
COMPILER = {"fusestatic": "false", "discardvisual": "false", "inertiafromgeom": "false",
            "strippath": "false", "angle": "radian"}


@dataclass
class Converted:
    """The robot as an MjSpec (no world, no actuators yet) and the conversion's notes."""

    spec: mujoco.MjSpec
    notes: list[str] = field(default_factory=list)
    meshes: dict[str, str] = field(default_factory=dict)  # URI as written -> absolute path


def welded_mass(urdf: Urdf, link: str) -> float:
    """The mass of ``link`` and every link fixed to it below (what moves with it as one)."""
    total = urdf.links[link].mass or 0.0
    for joint in urdf.children(link):
        if joint.kind == "fixed":
            total += welded_mass(urdf, joint.child)
    return total


def check_masses(urdf: Urdf, description: str, free_base: bool) -> list[str]:
    """DescriptionError for a moving link MuJoCo cannot simulate; notes for massless
    links that carry geometry (kept, as frames with no mass)."""
    moving = [(j.child, j.name) for j in urdf.joints.values() if j.kind != "fixed"]
    if free_base:
        moving.insert(0, (urdf.root, None))
    for link, joint in moving:
        if welded_mass(urdf, link) < MIN_MASS:
            why = "has no <inertial>" if urdf.links[link].mass is None else "has zero mass"
            moved = f"joint {joint!r} moves it" if joint else "it is the mobile robot's root"
            raise DescriptionError(
                description, f"the link {why}, and {moved}: MuJoCo cannot simulate a massless "
                "moving body", link=link,
                fix=f'give link "{link}" an <inertial> with <mass value> > 0 and ixx, iyy, '
                    "izz > 0 (or make its joint fixed)")
        inertia = urdf.links[link].inertia
        if urdf.links[link].mass and inertia is not None and min(inertia) <= 0 and \
                welded_mass(urdf, link) == urdf.links[link].mass:
            raise DescriptionError(
                description, f"the moving link's inertia {inertia} is not positive", link=link,
                fix="give ixx, iyy and izz > 0 in its <inertial><inertia>")
    return [f"link {name!r} has no <inertial>: kept as a massless frame fixed to its parent"
            for name, link in urdf.links.items()
            if link.mass is None and (link.visuals or link.collisions)
            and name not in {m for m, _ in moving}]


def _mesh_of(el: ET.Element) -> ET.Element | None:
    geometry = el.find("geometry")
    return None if geometry is None else geometry.find("mesh")


def resolve_meshes(root: ET.Element, description: str, resolver: PackageResolver,
                   base: Path) -> tuple[list[str], dict[str, str]]:
    """Rewrite every mesh filename as an absolute path and replace COLLADA visuals; notes
    and the URI -> path map. DescriptionError for an unknown package or a missing file."""
    notes, meshes = [], {}
    for link in root.findall("link"):
        name = link.get("name", "")
        replaced = []
        for role in ("visual", "collision"):
            for el in link.findall(role):
                mesh = _mesh_of(el)
                if mesh is None:
                    continue
                uri = mesh.get("filename", "")
                try:
                    path = resolver.resolve_uri(uri, base)
                except PackageNotFound as exc:
                    raise DescriptionError(
                        description, f"{role} mesh {uri!r}: {exc}", link=name,
                        fix=f"add '{exc.package}: /path/to/{exc.package}' to the robot's "
                            "packages:, or source the workspace that has it") from None
                if not path.is_file():
                    raise DescriptionError(description, f"{role} mesh {uri!r} does not exist",
                                           link=name, path=str(path),
                                           fix="correct the filename or add the file")
                try:
                    parts = mujoco_meshes(path, whole=role == "collision")
                except MeshError as exc:
                    if role == "collision":
                        raise DescriptionError(description, f"{role} mesh {uri!r}: {exc}",
                                               link=name, path=str(path),
                                               fix="re-export it as binary STL or OBJ") from None
                    link.remove(el)
                    replaced.append(f"{uri} ({exc})")
                    continue
                if parts is not None:
                    _use_parts(link, el, parts)
                    meshes[uri] = parts[0].path
                    kind = "COLLADA" if path.suffix.lower() == ".dae" else "ASCII STL"
                    split = f" ({len(parts)} parts, one per colour)" if len(parts) > 1 else ""
                    notes.append(f"link {name!r}: {role} mesh {uri!r} ({kind}) converted to "
                                 f"binary STL{split}")
                    continue
                if path.suffix.lower() not in MESH_FORMATS:
                    if role == "collision":
                        raise DescriptionError(
                            description, f"collision mesh {uri!r} is a {path.suffix} file, "
                            "which MuJoCo cannot read", link=name, path=str(path),
                            fix="convert it to STL or OBJ (e.g. with meshlab or trimesh)")
                    link.remove(el)
                    replaced.append(f"{uri} (MuJoCo cannot read {path.suffix} files)")
                    continue
                mesh.set("filename", str(path))
                meshes[uri] = str(path)
        if replaced:
            for col in link.findall("collision"):
                visual = ET.SubElement(link, "visual")
                for child in col:
                    visual.append(child)
            drawn = "its collision geometry" if link.findall("collision") else "nothing"
            notes.append(f"link {name!r}: visual mesh {', '.join(replaced)} not drawn: "
                         f"drawn with {drawn} instead")
    return notes, meshes


def _use_parts(link: ET.Element, el: ET.Element, parts: list[MeshPart]) -> None:
    """Point ``el`` (a visual or collision) at the converted mesh; a visual of several
    coloured parts becomes one visual per part, each with its part's colour."""
    position = list(link).index(el)
    for i, part in enumerate(parts):
        target = el if i == 0 else copy.deepcopy(el)
        _mesh_of(target).set("filename", part.path)
        if part.rgba is not None and el.tag == "visual":
            for old in target.findall("material"):
                target.remove(old)
            material = ET.SubElement(target, "material")
            ET.SubElement(material, "color", rgba=" ".join(f"{c:g}" for c in part.rgba))
        if i:
            link.insert(position + i, target)


def _compiler(root: ET.Element) -> list[str]:
    """Put cosim's compiler settings into the document's ``<mujoco>`` extension."""
    notes = []
    ext = root.find("mujoco")
    if ext is None:
        ext = ET.SubElement(root, "mujoco")
    compiler = ext.find("compiler")
    if compiler is None:
        compiler = ET.SubElement(ext, "compiler")
    for key, value in COMPILER.items():
        if compiler.get(key) not in (None, value):
            notes.append(f"<mujoco><compiler {key}={compiler.get(key)!r}> overridden with "
                         f"{value!r} (cosim keeps every link, visual and mass as given)")
        compiler.set(key, value)
    for tag in ("gazebo", "ros2_control", "transmission"):
        for el in root.findall(tag):
            root.remove(el)
    return notes


def convert(urdf: Urdf, text: str, description: str, resolver: PackageResolver,
            base: Path, free_base: bool) -> Converted:
    """The URDF as an MjSpec: every link a body with a site, geoms named and grouped, a free
    joint at the root when ``free_base``. DescriptionError when MuJoCo refuses it."""
    notes = check_masses(urdf, description, free_base)
    root = ET.fromstring(text)
    mesh_notes, meshes = resolve_meshes(root, description, resolver, base)
    notes += mesh_notes + _compiler(root)
    try:
        spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    except ValueError as exc:
        raise DescriptionError(description, f"MuJoCo's URDF compiler refuses it: {exc}",
                               fix="see MuJoCo's message") from None
    for body in spec.bodies:
        if body.name == "world" and body.parent is None:
            continue
        _name_geoms(body, urdf.friction.get(body.name))
        site = body.add_site(name=body.name, size=[0.01, 0.01, 0.01], group=SITE_GROUP)
        site.rgba = [1, 0.5, 0, 1]
    if urdf.root == "world":
        # the URDF's world frame is where the robot stands: a site on the world body that
        # moves with the robot's placement (MuJoCo's compiler made the link the world body)
        site = spec.worldbody.add_site(name=WORLD_SITE, size=[0.01, 0.01, 0.01],
                                       group=SITE_GROUP)
        site.rgba = [1, 0.5, 0, 1]
    if free_base:
        spec.body(urdf.root).add_freejoint(name=f"{urdf.root}_free")
    for joint in urdf.joints.values():
        # adjacent links never collide (as in Gazebo and MoveIt); MuJoCo's own parent filter
        # lapses where the parent is welded to the world (a fixed arm's base)
        if "world" not in (joint.parent, joint.child):
            spec.add_exclude(bodyname1=joint.parent, bodyname2=joint.child)
    for joint in urdf.joints.values():
        if joint.mimic:
            notes.append(f"joint {joint.name!r} mimics {joint.mimic!r}: the mimic is not "
                         "enforced (it moves on its own)")
        if joint.kind == "planar":
            notes.append(f"joint {joint.name!r} is planar: MuJoCo's URDF compiler reads it "
                         "as its own approximation")
    if urdf.unsupported:
        notes.append(f"elements ignored: {', '.join('<' + t + '>' for t in urdf.unsupported)}")
    return Converted(spec, notes, meshes)


def _name_geoms(body: mujoco.MjsBody, friction: float | None) -> None:
    visual = collision = 0
    for geom in body.geoms:
        if geom.contype == 0 and geom.conaffinity == 0 and geom.group == 1:
            geom.name, geom.group = f"{body.name}_visual_{visual}", VISUAL_GROUP
            visual += 1
        else:
            geom.name, geom.group = f"{body.name}_collision_{collision}", COLLISION_GROUP
            collision += 1
            if friction is not None:
                geom.friction[0] = friction
                geom.priority = 1  # its own friction wins over the floor's, as Gazebo's mu
                if friction == 0:
                    geom.condim = 1
