"""A robot described in OpenUSD read into plain data with ``pxr.UsdPhysics``: its links
(rigid bodies, and plain Xforms below them kept as frames), joints (revolute, prismatic,
fixed; ``physics:body0`` the parent, ``physics:body1`` the child), drives, geometry,
cameras, and what the converters keep beside (urdf-usd-converter's ``urdf:`` custom scopes:
``<ros2_control>``, ``<gazebo>``, ``<transmission>``). Every name is a prim's NAME, never
its path; every pose is in metres, +Z up (``descriptions.worldfile.open_stage``).

The layouts read (docs/how-to/usd-robots.md):

- Isaac Sim's URDF importer: links as rigid bodies under the robot prim, joints in a
  ``joints`` scope, ``PhysicsDriveAPI:angular|linear`` on driven joints, revolute limits in
  degrees, ``ArticulationRootAPI`` on the root link of a mobile robot and a ``root_joint``
  holding a fixed base to the world;
- urdf-usd-converter (Isaac Sim 6.1+): links nested by the kinematic tree, joints in a
  ``Physics`` scope, no drives (effort as ``urdf:limit:effort``; ``newton:damping`` and
  ``newton:velocityLimit`` per degree), massless links as plain Xforms, both
  ``physics:diagonalInertia`` and ``newton:inertia`` (the first is used);
- mujoco-usd-converter: bodies nested, joints under their child bodies (fixed ones all named
  ``PhysicsFixedJoint``), actuators as ``MjcActuator`` prims, MJCF sites as spheres with
  ``MjcSiteAPI`` (no geometry).

A joint whose ``body0`` is empty, or is the robot prim itself, holds the robot to the world.
A joint whose ``body0`` is a plain Xform above ``body1`` (urdf-usd-converter's massless root
link) makes that Xform a frame link.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from descriptions.description_error import DescriptionError
from descriptions.usd_geometry import GPRIMS, Geom, link_geometry
from descriptions.usd_joints import (
    JOINT_TYPES,
    WORLD,
    Joint,
    misplaced,
    mjc_actuators,
    named_joints,
    read_joint,
    tree_order,
)
from descriptions.usd_prims import (
    UNLIMITED,
    api_schemas,
    get,
    matrix,
    matrix_quat,
    prims,
    quat,
    quat_matrix,
    snapped_pose,
    split_scale,
)

GEOMETRY_GROUPS = ("visuals", "collisions")  # Isaac's importer's Xforms under a link


CUSTOM_TAGS = ("ros2_control", "gazebo", "transmission")


BOTH_INERTIA = "physics:diagonalInertia and newton:inertia both given on links "


@dataclass
class Link:
    """A link: its prim's name and path, world pose (4x4, no scale), mass properties (None:
    none authored), geometry, and whether it is a rigid body or a plain Xform frame."""

    name: str
    prim: str
    pose: np.ndarray
    rigid: bool
    mass: float | None = None
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[float, float, float] | None = None
    principal: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    geoms: list[Geom] = field(default_factory=list)
    camera: Camera | None = None


@dataclass
class Camera:
    """A ``UsdGeom.Camera``: its prim, the link it hangs on and its field of view."""

    name: str
    prim: str
    parent: str
    horizontal_fov: float
    clip: tuple[float, float]


@dataclass
class StageRobot:
    """The robot of a stage: its prim, links and joints (file order), the root link, the
    converters' kept URDF elements (``<ros2_control>``, ``<gazebo>``, ``<transmission>``)
    and the notes on what was not read."""

    name: str
    prim: str
    links: dict[str, Link]
    joints: dict[str, Joint]
    root: str
    articulated: bool
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))  # the robot prim's
    kept: list[ET.Element] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def world_joint(self) -> Joint | None:
        """The joint holding the robot to the world (Isaac's ``root_joint``), if any."""
        return next((j for j in self.joints.values() if j.parent == WORLD), None)


def read_stage_robot(stage, description: str) -> StageRobot:
    """The robot of ``stage`` (opened in metres, Z-up); DescriptionError naming the prim
    for a joint whose body is missing, a robot with no root or no single tree."""
    from pxr import Usd, UsdGeom, UsdPhysics

    top = stage.GetDefaultPrim() or next(iter(stage.GetPseudoRoot().GetChildren()), None)
    if top is None:
        raise DescriptionError(description, "the stage has no prim", fix="a USD robot asset "
                               "(a default prim holding the robot's links and joints)")
    cache = UsdGeom.XformCache(Usd.TimeCode.Default())
    meters, kilograms = stage_units(stage)
    notes: list[str] = []
    rigid = [p for p in prims(top) if p.HasAPI(UsdPhysics.RigidBodyAPI)]
    if not rigid:
        raise DescriptionError(description, "no prim has PhysicsRigidBodyAPI: this is no "
                               "robot (a world whose prims name an MJCF robot is a world:, "
                               "not a robots.description)", prim=str(top.GetPath()),
                               fix="a robot asset with UsdPhysics rigid bodies and joints, "
                                   "as Isaac Sim's URDF importer or urdf-usd-converter "
                                   "writes it")
    links: dict[str, Link] = {}
    by_path: dict[str, str] = {}

    def add_link(prim, is_rigid: bool) -> str:
        name = prim.GetName()
        if name in links and links[name].prim != str(prim.GetPath()):
            raise DescriptionError(description, f"two links are named {name!r} ("
                                   f"{links[name].prim} and {prim.GetPath()}); joint and "
                                   "link names are the prims' names", prim=str(prim.GetPath()),
                                   fix="give every link prim its own name")
        pose, _ = split_scale(matrix(cache.GetLocalToWorldTransform(prim)))
        links.setdefault(name, Link(name, str(prim.GetPath()), pose, is_rigid))
        by_path[str(prim.GetPath())] = name
        return name

    for prim in rigid:
        add_link(prim, True)
        _mass(links[prim.GetName()], prim, notes, meters, kilograms)
    articulated = any(p.HasAPI(UsdPhysics.ArticulationRootAPI) for p in prims(top))

    found: list[Joint] = []
    for prim in prims(top):
        if not prim.IsA(UsdPhysics.Joint):
            continue
        where = str(prim.GetPath())
        kind = JOINT_TYPES.get(prim.GetTypeName())
        if kind is None:
            notes.append(f"joint {prim.GetName()!r} ({prim.GetTypeName()}): a type cosim does "
                         "not read (revolute, prismatic, fixed), ignored")
            continue
        joint = UsdPhysics.Joint(prim)
        if get(prim, "physics:jointEnabled", True) is False:
            notes.append(f"joint {prim.GetName()!r} is disabled (physics:jointEnabled), ignored")
            continue
        if get(prim, "physics:excludeFromArticulation", False):
            notes.append(f"joint {prim.GetName()!r} is excluded from the articulation (a "
                         "loop), ignored")
            continue
        ends = []
        for i, rel in enumerate((joint.GetBody0Rel(), joint.GetBody1Rel())):
            targets = rel.GetTargets()
            if not targets:
                if i == 1:
                    raise DescriptionError(description, "the joint has no physics:body1 (the "
                                           "child body)", prim=where,
                                           fix="set physics:body1 to the child link's prim")
                ends.append(None)
                continue
            body = stage.GetPrimAtPath(targets[0])
            if not body:
                raise DescriptionError(description, f"physics:body{i} names {targets[0]}, "
                                       "which is not in the stage", prim=where,
                                       fix=f"point physics:body{i} at an existing link prim")
            ends.append(body)
        parent = _parent_link(ends[0], ends[1], top, by_path, add_link)
        child_prim = ends[1]
        if str(child_prim.GetPath()) not in by_path:
            if kind != "fixed" or child_prim.GetTypeName() not in ("Xform", ""):
                raise DescriptionError(description, f"physics:body1 {child_prim.GetPath()} is "
                                       "not a rigid body: the joint moves nothing",
                                       prim=where, fix="apply PhysicsRigidBodyAPI (and "
                                       "PhysicsMassAPI) to the child link")
            add_link(child_prim, False)
        child = by_path[str(child_prim.GetPath())]
        found.append(read_joint(prim, kind, parent, child, (meters, kilograms), notes,
                            prim.GetName()))
    joints = named_joints(description, found, notes)

    mjc_actuators(description, top, joints, notes)
    _frames(top, links, joints, by_path, add_link, cache)
    for link in links.values():
        link.geoms = link_geometry(stage.GetPrimAtPath(link.prim), link.name, by_path, cache,
                                   notes)
    kept = _kept_elements(top)
    notes += _unread(top)
    _check_tree(description, links, joints, articulated)
    roots = [n for n in links if n not in {j.child for j in joints.values()
                                           if j.parent != WORLD}]
    joints = tree_order(joints, roots[0])
    notes += misplaced({name: link.pose for name, link in links.items()}, joints)
    frames = [n for n, k in links.items() if not k.rigid and k.camera is None]
    if frames:
        notes.append(f"plain Xforms kept as frames (links without mass): {', '.join(frames)}")
    order = [roots[0], *(j.child for j in joints.values())]
    links = {name: links[name] for name in order + [n for n in links if n not in order]}
    top_pose, _ = split_scale(matrix(cache.GetLocalToWorldTransform(top)))
    if _source_up_axis(stage) == "Y":  # keep open_stage's turn of +Y up to +Z up
        up = np.eye(4)
        up[:3, :3] = quat_matrix(math.cos(math.pi / 4), math.sin(math.pi / 4), 0, 0)
        top_pose = top_pose @ np.linalg.inv(snapped_pose(up))
    return StageRobot(top.GetName(), str(top.GetPath()), links, joints, roots[0],
                      articulated, top_pose, kept, notes)


def _source_up_axis(stage) -> str:
    from pxr import Sdf

    subs = stage.GetRootLayer().subLayerPaths
    layer = Sdf.Layer.FindOrOpen(subs[0]) if subs else stage.GetRootLayer()
    info = layer.pseudoRoot
    return str(info.GetInfo("upAxis")) if info.HasInfo("upAxis") else "Y"


def stage_units(stage) -> tuple[float, float]:
    """(metres, kilograms) per unit of the file under ``open_stage``'s root layer (which says
    metres): USD's fallbacks are centimetres and kilograms."""
    from pxr import Sdf

    subs = stage.GetRootLayer().subLayerPaths
    layer = Sdf.Layer.FindOrOpen(subs[0]) if subs else stage.GetRootLayer()
    info = layer.pseudoRoot
    meters = info.GetInfo("metersPerUnit") if info.HasInfo("metersPerUnit") else 0.01
    kilograms = info.GetInfo("kilogramsPerUnit") if info.HasInfo("kilogramsPerUnit") else 1.0
    return float(meters), float(kilograms)


def _parent_link(body0, body1, top, by_path: dict[str, str], add_link) -> str:
    """The parent link of a joint: a rigid body; ``world`` for an empty body0 or the robot
    prim; a plain Xform that is body0 or lies between body0 and body1 (the deepest such,
    urdf-usd-converter's massless root link) as a frame link."""
    if body0 is None:
        return WORLD
    path = str(body0.GetPath())
    if path in by_path:
        return by_path[path]
    prim = body1.GetParent()
    while prim and prim != body0 and prim.GetPath().HasPrefix(body0.GetPath()):
        if prim.GetTypeName() == "Xform" and prim != top:
            return by_path.get(str(prim.GetPath())) or add_link(prim, False)
        prim = prim.GetParent()
    if body0 == top or body0.GetTypeName() != "Xform":
        return WORLD
    return add_link(body0, False)


def _mass(link: Link, prim, notes: list[str], meters: float, kilograms: float) -> None:
    from pxr import UsdPhysics

    if not prim.HasAPI(UsdPhysics.MassAPI):
        return
    mass = get(prim, "physics:mass")
    if mass is None or mass <= 0:
        if get(prim, "physics:density"):
            notes.append(f"link {link.name!r}: mass from physics:density is not computed "
                         "(only an authored physics:mass is read)")
        return
    link.mass = float(mass) * kilograms
    com = get(prim, "physics:centerOfMass")
    if com is not None and all(math.isfinite(v) and abs(v) < UNLIMITED for v in com):
        link.com = tuple(float(v) * meters for v in com)
    diagonal = get(prim, "physics:diagonalInertia")
    full = get(prim, "newton:inertia")
    if diagonal is not None and any(v > 0 for v in diagonal):
        link.inertia = tuple(float(v) * kilograms * meters ** 2 for v in diagonal)
        axes = get(prim, "physics:principalAxes")
        if axes is not None:
            link.principal = quat(axes)
        if full is not None:
            both = next((n for n in notes if n.startswith(BOTH_INERTIA)), None)
            if both is not None:
                notes.remove(both)
            names = [] if both is None else both[len(BOTH_INERTIA):].split(": ")[0].split(", ")
            notes.append(f"{BOTH_INERTIA}{', '.join([*names, link.name])}: "
                         "physics:diagonalInertia (with physics:principalAxes) is used")
    elif full is not None and len(full) == 6:
        ixx, iyy, izz, ixy, ixz, iyz = (float(v) for v in full)
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        values, vectors = np.linalg.eigh(tensor)
        if np.linalg.det(vectors) < 0:
            vectors[:, 0] *= -1
        link.inertia = tuple(float(v) * kilograms * meters ** 2 for v in values)
        link.principal = matrix_quat(vectors)


def _frames(top, links: dict[str, Link], joints: dict[str, Joint], by_path, add_link,
            cache) -> None:
    """Plain Xforms below a link holding no geometry (sensor frames, massless links that
    urdf-usd-converter kept as Xforms) become frame links, fixed to the link above, and
    ``UsdGeom.Camera`` prims cameras on the link above."""
    from pxr import Usd, UsdGeom

    it = iter(prims(top))
    for prim in it:
        path = str(prim.GetPath())
        owner = _owner(prim, by_path)
        if prim.IsA(UsdGeom.Camera) and owner is not None:
            cam = UsdGeom.Camera(prim).GetCamera(Usd.TimeCode.Default())
            name = add_link(prim, False)
            _frame_joint(joints, path, owner, name)
            links[name].camera = Camera(
                name, path, owner, 2 * math.atan(cam.horizontalAperture / 2 / cam.focalLength),
                (float(cam.clippingRange.min), float(cam.clippingRange.max)))
            it.PruneChildren()
            continue
        if path in by_path or owner is None or prim.GetTypeName() != "Xform" or \
                prim.GetName() in GEOMETRY_GROUPS:
            continue
        if any(q.GetTypeName() in GPRIMS for q in prims(prim)):
            continue
        _frame_joint(joints, path, owner, add_link(prim, False))


def _frame_joint(joints: dict[str, Joint], path: str, parent: str, child: str) -> None:
    """The fixed joint a frame hangs on, named CHILD_joint (CHILD_frame_joint if taken)."""
    name = next(n for n in (f"{child}_joint", f"{child}_frame_joint", f"{path}_joint")
                if n not in joints)
    joints[name] = Joint(name, path, "fixed", parent, child)


def _owner(prim, by_path: dict[str, str]) -> str | None:
    """The link a prim lies under (the nearest link prim above it), None if none."""
    parent = prim.GetParent()
    while parent and not parent.IsPseudoRoot():
        if str(parent.GetPath()) in by_path:
            return by_path[str(parent.GetPath())]
        parent = parent.GetParent()
    return None


READ_SCHEMAS = {"PhysicsRigidBodyAPI", "PhysicsMassAPI", "PhysicsCollisionAPI",
                "PhysicsMeshCollisionAPI", "PhysicsArticulationRootAPI", "PhysicsDriveAPI",
                "PhysicsMaterialAPI", "MaterialBindingAPI", "NewtonJointAPI", "NewtonMassAPI",
                "NewtonCollisionAPI", "NewtonMeshCollisionAPI", "NewtonArticulationRootAPI",
                "GeomModelAPI", "PhysxJointAPI", "MjcJointAPI", "MjcSiteAPI", "NewtonSiteAPI",
                "NodeDefAPI", "ConnectableAPI", "CoordSysAPI"}  # shading: drawn, no physics


READ_TYPES = {"", "Xform", "Scope", "Material", "Shader", "Camera", "PhysicsScene",
              *GPRIMS, *JOINT_TYPES, "GeomSubset", "DistantLight", "DomeLight", "MjcActuator"}


def _unread(top) -> list[str]:
    """One note naming the prim types and applied schemas under the robot that cosim does
    not read (PhysX settings, sensors of Isaac's own schemas, ...), with a count each."""

    types: dict[str, int] = {}
    schemas: dict[str, int] = {}
    for prim in prims(top):
        if prim.GetTypeName() not in READ_TYPES:
            types[prim.GetTypeName()] = types.get(prim.GetTypeName(), 0) + 1
        for schema in api_schemas(prim):
            base = str(schema).split(":")[0]
            if base not in READ_SCHEMAS:
                schemas[base] = schemas.get(base, 0) + 1
    out = []
    if types:
        out.append("prim types not read: " + ", ".join(f"{t} ({n})"
                                                       for t, n in sorted(types.items())))
    if schemas:
        out.append("applied schemas not read: " + ", ".join(
            f"{t} ({n})" for t, n in sorted(schemas.items())))
    return out


def _kept_elements(top) -> list[ET.Element]:
    """urdf-usd-converter keeps the URDF elements USD has no schema for as scopes of
    ``urdf:`` attributes (``custom/ros2_control``, ``custom/gazebo``): back to XML."""
    out = []
    for prim in top.GetAllChildren():
        for scope in [prim, *prim.GetAllChildren()]:
            if scope.GetName() != "custom":
                continue
            for element in scope.GetAllChildren():
                if _tag(element) in CUSTOM_TAGS:
                    out.append(_element(element))
    return out


def _tag(prim) -> str:
    return prim.GetDisplayName() or prim.GetName()


def _element(prim) -> ET.Element:
    el = ET.Element(_tag(prim))
    for attr in prim.GetAttributes():
        name = attr.GetName()
        if not name.startswith("urdf:"):
            continue
        if name == "urdf:text":
            el.text = str(attr.Get())
        else:
            el.set(name[len("urdf:"):], str(attr.Get()))
    for child in prim.GetAllChildren():
        el.append(_element(child))
    return el


def _check_tree(description: str, links: dict[str, Link], joints: dict[str, Joint],
                articulated: bool) -> None:
    children: dict[str, str] = {}
    for j in joints.values():
        if j.child in children:
            raise DescriptionError(description, f"link {j.child!r} is the child (physics:"
                                   f"body1) of two joints, {children[j.child]!r} and "
                                   f"{j.name!r}", prim=j.prim,
                                   fix="a link has one parent joint; mark a loop-closing "
                                       "joint physics:excludeFromArticulation = true")
        children[j.child] = j.name
    roots = [n for n in links if n not in children or joints[children[n]].parent == WORLD]
    if not roots:
        raise DescriptionError(description, "the robot has no root: every link is some "
                               "joint's child (a loop)", prim=next(iter(links.values())).prim,
                               fix="a tree of joints from one root link")
    if len(roots) > 1:
        raise DescriptionError(description, f"the links form {len(roots)} trees (roots "
                               f"{roots}), not one robot", prim=links[roots[1]].prim,
                               fix="join every link to one root link by a joint")
    if not articulated and not any(j.parent == WORLD for j in joints.values()):
        raise DescriptionError(description, "the robot has no root: no prim has "
                               "PhysicsArticulationRootAPI and no joint holds it to the world",
                               prim=links[roots[0]].prim,
                               fix="apply PhysicsArticulationRootAPI to the robot prim or its "
                                   "root link (Isaac Sim's importer does), or add a fixed "
                                   "root_joint from the world")
