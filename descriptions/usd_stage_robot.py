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
  ``physics:diagonalInertia`` and ``newton:inertia`` (the first is used).

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

WORLD = "world"
JOINT_TYPES = {"PhysicsRevoluteJoint": "revolute", "PhysicsPrismaticJoint": "prismatic",
               "PhysicsFixedJoint": "fixed"}
GPRIMS = ("Cube", "Sphere", "Cylinder", "Capsule", "Mesh")
GEOMETRY_GROUPS = ("visuals", "collisions")  # Isaac's importer's Xforms under a link
UNLIMITED = 1e17  # |limit| at or above this (or inf) is no limit
CUSTOM_TAGS = ("ros2_control", "gazebo", "transmission")
BOTH_INERTIA = "physics:diagonalInertia and newton:inertia both given on links "


@dataclass
class Geom:
    """One shape of a link: role (collision or visual), kind (box, sphere, cylinder,
    capsule, mesh), its pose in the prim's world frame (4x4, scale removed), sizes (box:
    full edges; sphere: radius; cylinder/capsule: radius, length along +z), mesh vertices
    (n, 3, scaled) and triangles, colour, friction (None: not authored), the prim."""

    role: str
    kind: str
    pose: np.ndarray
    size: tuple[float, ...]
    prim: str
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    rgba: tuple[float, float, float, float] | None = None
    friction: float | None = None


@dataclass
class Drive:
    """A ``PhysicsDriveAPI``: stiffness and damping in SI (per radian for an angular
    drive), the force limit (None: unlimited) and its type."""

    stiffness: float
    damping: float
    max_force: float | None
    kind: str = "force"


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
class Joint:
    """A joint: its prim's name and path, kind, parent (``world`` for the world) and child
    link names, the pivot and axis in the child link's frame, limits (rad or m; None: none),
    drive, effort and velocity limits, passive damping."""

    name: str
    prim: str
    kind: str
    parent: str
    child: str
    pivot: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    anchor: tuple[float, float, float] | None = None  # physics:localPos0, in the parent's
    lower: float | None = None
    upper: float | None = None
    drive: Drive | None = None
    effort: float | None = None
    velocity: float | None = None
    damping: float | None = None


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


def _matrix(m) -> np.ndarray:
    """A Gf.Matrix4d (row vectors) as a 4x4 numpy matrix acting on column vectors."""
    return np.array(m, dtype=float).T


EXACT = np.array([0.0, 0.5, math.sqrt(0.5), math.sqrt(0.75), 1.0])
SNAP = 1e-6  # float32 (quatf, matrix4d from float ops) is off right angles by ~1e-8


def snapped(r: np.ndarray) -> np.ndarray:
    """A rotation matrix with entries within SNAP of 0, 1/2, sqrt(1/2), sqrt(3/4) or 1 (in
    size) set to them: USD's float32 quaternions tilt a wheel turned by 90 degrees by ~1e-8
    rad, and MuJoCo's cylinder-on-plane contact then gives one contact instead of two."""
    out = r.copy()
    for idx, v in np.ndenumerate(r):
        near = EXACT[np.argmin(np.abs(EXACT - abs(v)))]
        if abs(abs(v) - near) < SNAP:
            out[idx] = math.copysign(near, v) if near else 0.0
    u, _, vt = np.linalg.svd(out)
    return u @ vt if np.abs(u @ vt - out).max() > 1e-12 else out


def split_scale(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the pose without scale, the scale per axis) of a 4x4 transform (no shear)."""
    scale = np.linalg.norm(t[:3, :3], axis=0)
    pose = np.eye(4)
    pose[:3, :3] = t[:3, :3] / np.where(scale > 0, scale, 1.0)
    pose[:3, 3] = t[:3, 3]
    if np.linalg.det(pose[:3, :3]) < 0:  # a mirror: keep a rotation, put the flip in scale
        pose[:3, 0] *= -1
        scale[0] *= -1
    pose[:3, :3] = snapped(pose[:3, :3])
    return pose, scale


def quat_matrix(w: float, x: float, y: float, z: float) -> np.ndarray:
    """The rotation matrix of a quaternion (normalised first)."""
    n = math.sqrt(w * w + x * x + y * y + z * z) or 1.0
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _quat(q) -> tuple[float, float, float, float]:
    return (float(q.GetReal()), *(float(v) for v in q.GetImaginary()))


def _get(prim, name: str, default=None):
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasAuthoredValue():
        return default
    return attr.Get()


def _limit(value) -> float | None:
    return None if value is None or not math.isfinite(value) or abs(value) >= UNLIMITED \
        else float(value)


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
    rigid = [p for p in _prims(top) if p.HasAPI(UsdPhysics.RigidBodyAPI)]
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
        pose, _ = split_scale(_matrix(cache.GetLocalToWorldTransform(prim)))
        links.setdefault(name, Link(name, str(prim.GetPath()), pose, is_rigid))
        by_path[str(prim.GetPath())] = name
        return name

    for prim in rigid:
        add_link(prim, True)
        _mass(links[prim.GetName()], prim, notes, meters, kilograms)
    articulated = any(p.HasAPI(UsdPhysics.ArticulationRootAPI) for p in _prims(top))

    found: list[Joint] = []
    for prim in _prims(top):
        if not prim.IsA(UsdPhysics.Joint):
            continue
        where = str(prim.GetPath())
        kind = JOINT_TYPES.get(prim.GetTypeName())
        if kind is None:
            notes.append(f"joint {prim.GetName()!r} ({prim.GetTypeName()}): a type cosim does "
                         "not read (revolute, prismatic, fixed), ignored")
            continue
        joint = UsdPhysics.Joint(prim)
        if _get(prim, "physics:jointEnabled", True) is False:
            notes.append(f"joint {prim.GetName()!r} is disabled (physics:jointEnabled), ignored")
            continue
        if _get(prim, "physics:excludeFromArticulation", False):
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
        found.append(_joint(prim, kind, parent, child, (meters, kilograms), notes,
                            prim.GetName()))
    joints = _named(description, found, notes)

    _mjc_actuators(top, joints, notes)
    _frames(top, links, joints, by_path, add_link, cache)
    for link in links.values():
        _geometry(stage.GetPrimAtPath(link.prim), link, by_path, cache, notes)
    kept = _kept_elements(top)
    notes += _unread(top)
    _check_tree(description, links, joints, articulated)
    roots = [n for n in links if n not in {j.child for j in joints.values()
                                           if j.parent != WORLD}]
    joints = _tree_order(joints, roots[0])
    notes += _misplaced(links, joints)
    frames = [n for n, k in links.items() if not k.rigid and k.camera is None]
    if frames:
        notes.append(f"plain Xforms kept as frames (links without mass): {', '.join(frames)}")
    order = [roots[0], *(j.child for j in joints.values())]
    links = {name: links[name] for name in order + [n for n in links if n not in order]}
    top_pose, _ = split_scale(_matrix(cache.GetLocalToWorldTransform(top)))
    if _source_up_axis(stage) == "Y":  # keep open_stage's turn of +Y up to +Z up
        up = np.eye(4)
        up[:3, :3] = quat_matrix(math.cos(math.pi / 4), math.sin(math.pi / 4), 0, 0)
        top_pose = top_pose @ np.linalg.inv(snapped_pose(up))
    return StageRobot(top.GetName(), str(top.GetPath()), links, joints, roots[0],
                      articulated, top_pose, kept, notes)


def _named(description: str, found: list[Joint], notes: list[str]) -> dict[str, Joint]:
    """The joints by name: the prim's, but fixed joints whose prim name several share
    (mujoco-usd-converter's ``PhysicsFixedJoint``) are named CHILD_joint; two moving joints
    of one name are a DescriptionError."""
    names = [j.name for j in found]
    joints: dict[str, Joint] = {}
    renamed = []
    for joint in found:
        if names.count(joint.name) > 1:
            if joint.kind != "fixed":
                other = next(j for j in found if j.name == joint.name and j is not joint)
                raise DescriptionError(description, f"two joints are named {joint.name!r} ("
                                       f"{other.prim} and {joint.prim}); joint names are the "
                                       "prims' names", prim=joint.prim,
                                       fix="give every moving joint prim its own name")
            joint.name = next(n for n in (f"{joint.child}_joint", f"{joint.child}_fixed_joint",
                                          joint.prim) if n not in joints and n not in names)
            renamed.append(joint.name)
        joints[joint.name] = joint
    if renamed:
        notes.append(f"fixed joints sharing a prim name named by their child link: "
                     f"{', '.join(renamed)}")
    return joints


def _misplaced(links: dict[str, Link], joints: dict[str, Joint]) -> list[str]:
    """Joints whose two frames (``localPos0`` on the parent, ``localPos1`` on the child) are
    more than 1 mm apart where the prims stand: the bodies are placed by their prims, as
    authored, and the joint turns the child about its own frame."""
    off = []
    for j in joints.values():
        if j.parent == WORLD or j.anchor is None or j.parent not in links:
            continue
        a = links[j.parent].pose @ np.array([*j.anchor, 1.0])
        b = links[j.child].pose @ np.array([*j.pivot, 1.0])
        if np.linalg.norm(a - b) > 1e-3:
            off.append(f"{j.name} ({np.linalg.norm(a - b) * 1000:.1f} mm)")
    return [f"joint frames apart where the bodies stand, bodies kept where their prims put "
            f"them: {', '.join(off)}"] if off else []


def _tree_order(joints: dict[str, Joint], root: str) -> dict[str, Joint]:
    """The joints from the root down (the world's joint first, then depth first, siblings in
    the stage's order), as a URDF lists them: a layout that nests joints under their child
    links (mujoco-usd-converter) lists the deepest first."""
    order = [j for j in joints.values() if j.parent == WORLD]

    def below(link: str) -> None:
        for joint in joints.values():
            if joint.parent == link:
                order.append(joint)
                below(joint.child)

    below(root)
    order += [j for j in joints.values() if j not in order]
    return {j.name: j for j in order}


def _prims(prim):
    """Every prim from ``prim`` down, into instances too (Isaac's importer makes its meshes
    instanceable: their colliders live in the instances' prototypes)."""
    from pxr import Usd

    return Usd.PrimRange(prim, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate))


def snapped_pose(t: np.ndarray) -> np.ndarray:
    """A 4x4 pose with its rotation snapped (``snapped``)."""
    t = t.copy()
    t[:3, :3] = snapped(t[:3, :3])
    return t


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
    mass = _get(prim, "physics:mass")
    if mass is None or mass <= 0:
        if _get(prim, "physics:density"):
            notes.append(f"link {link.name!r}: mass from physics:density is not computed "
                         "(only an authored physics:mass is read)")
        return
    link.mass = float(mass) * kilograms
    com = _get(prim, "physics:centerOfMass")
    if com is not None and all(math.isfinite(v) and abs(v) < UNLIMITED for v in com):
        link.com = tuple(float(v) * meters for v in com)
    diagonal = _get(prim, "physics:diagonalInertia")
    full = _get(prim, "newton:inertia")
    if diagonal is not None and any(v > 0 for v in diagonal):
        link.inertia = tuple(float(v) * kilograms * meters ** 2 for v in diagonal)
        axes = _get(prim, "physics:principalAxes")
        if axes is not None:
            link.principal = _quat(axes)
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
        link.principal = _matrix_quat(vectors)


def _matrix_quat(r: np.ndarray) -> tuple[float, float, float, float]:
    import mujoco

    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(r, dtype=float).ravel())
    return tuple(float(v) for v in q)


def _joint(prim, kind: str, parent: str, child: str, units: tuple[float, float],
           notes: list[str], name: str) -> Joint:
    meters, kilograms = units
    pivot = tuple(float(v) * meters for v in (_get(prim, "physics:localPos1") or (0, 0, 0)))
    rot1 = _get(prim, "physics:localRot1")
    r1 = np.eye(3) if rot1 is None else snapped(quat_matrix(*_quat(rot1)))
    axis_token = str(_get(prim, "physics:axis", "X"))
    unit = {"X": (1.0, 0, 0), "Y": (0, 1.0, 0), "Z": (0, 0, 1.0)}.get(axis_token, (1.0, 0, 0))
    axis = tuple(float(round(v, 12)) + 0.0 for v in r1 @ np.array(unit))
    pos0 = _get(prim, "physics:localPos0")
    anchor = None if pos0 is None else tuple(float(v) * meters for v in pos0)
    joint = Joint(name, str(prim.GetPath()), kind, parent, child, pivot, axis, anchor)
    if kind == "fixed":
        return joint
    degrees = kind == "revolute"
    # to SI: a force is kg * unit / s^2, a torque kg * unit^2 / s^2; angles in degrees
    gain_scale = kilograms * (180.0 / math.pi * meters ** 2 if degrees else 1.0)  # per rad
    force_scale = kilograms * (meters ** 2 if degrees else meters)
    speed_scale = math.pi / 180.0 if degrees else meters
    lower = _limit(_get(prim, "physics:lowerLimit"))
    upper = _limit(_get(prim, "physics:upperLimit"))
    if degrees:
        lower = None if lower is None else math.radians(lower)
        upper = None if upper is None else math.radians(upper)
    elif lower is not None:
        lower, upper = lower * meters, None if upper is None else upper * meters
    joint.lower, joint.upper = lower, upper
    joint.drive = _drive(prim, "angular" if degrees else "linear", gain_scale, force_scale,
                         name, notes)
    effort = _get(prim, "urdf:limit:effort", _get(prim, "mjc:actuatorfrcrange:max"))
    if joint.drive is not None and joint.drive.max_force is not None:
        joint.effort = joint.drive.max_force
    elif effort is not None and effort > 0:
        joint.effort = float(effort)
    for attr, scale in (("physxJoint:maxJointVelocity", speed_scale),
                        ("newton:velocityLimit", speed_scale),
                        ("urdf:limit:velocity", 1.0)):
        value = _limit(_get(prim, attr))
        if value is not None and value > 0:
            joint.velocity = value * scale
            break
    for attr in ("physxJoint:jointFriction", "physxJoint:armature", "mjc:frictionloss",
                 "mjc:armature"):
        if _get(prim, attr):
            notes.append(f"joint {name!r}: {attr} {_get(prim, attr):g} not read")
    for attr, scale in (("newton:damping", gain_scale), ("mjc:damping", 1.0)):
        value = _get(prim, attr)
        if value is not None and value > 0:
            joint.damping = float(value) * scale
            break
    return joint


def api_schemas(prim) -> set[str]:
    """The API schemas applied to ``prim``, registered or not (mujoco-usd-converter's
    ``MjcSiteAPI`` is unknown to usd-core alone)."""
    names = {str(s) for s in prim.GetAppliedSchemas()}
    listed = prim.GetMetadata("apiSchemas")
    if listed is not None:
        names |= {str(s) for s in listed.GetAddedOrExplicitItems()}
    return {n.split(":")[0] for n in names}


def _mjc_actuators(top, joints: dict[str, Joint], notes: list[str]) -> None:
    """mujoco-usd-converter's ``MjcActuator`` prims as drives of the joints they target: a
    position servo (gain kp, bias [0, -kp, -kv]), a velocity servo (gain kv, bias [0, 0,
    -kv]) or a motor; ``mjc:forceRange`` the force limit."""

    by_prim = {j.prim: j for j in joints.values()}
    for prim in _prims(top):
        if prim.GetTypeName() != "MjcActuator":
            continue
        targets = prim.GetRelationship("mjc:target").GetTargets() \
            if prim.GetRelationship("mjc:target") else []
        joint = by_prim.get(str(targets[0])) if targets else None
        if joint is None or joint.kind == "fixed":
            notes.append(f"actuator {prim.GetName()!r}: its mjc:target is no moving joint, "
                         "ignored")
            continue
        gain = list(_get(prim, "mjc:gainPrm") or [1.0])
        bias = list(_get(prim, "mjc:biasPrm") or [0.0, 0.0, 0.0]) + [0.0, 0.0, 0.0]
        affine = str(_get(prim, "mjc:biasType", "none")) == "affine"
        kp = float(gain[0]) if affine and bias[1] < 0 else 0.0
        kv = -float(bias[2]) if affine and bias[2] < 0 else 0.0
        high = _get(prim, "mjc:forceRange:max")
        limited = str(_get(prim, "mjc:forceLimited", "false")) == "true"
        joint.drive = Drive(kp, kv, float(high) if limited and high else None)
        if joint.drive.max_force is not None:
            joint.effort = joint.drive.max_force
        if not affine and float(gain[0]) != 1.0:
            notes.append(f"actuator {prim.GetName()!r}: a motor with gear/gain {gain[0]:g}, "
                         "read as a plain effort command")


def _drive(prim, token: str, gain_scale: float, force_scale: float, joint: str,
           notes: list[str]) -> Drive | None:
    from pxr import UsdPhysics

    if not prim.HasAPI(UsdPhysics.DriveAPI, token):
        other = "linear" if token == "angular" else "angular"
        if prim.HasAPI(UsdPhysics.DriveAPI, other):
            notes.append(f"joint {joint!r}: a PhysicsDriveAPI:{other} on a "
                         f"{'revolute' if token == 'angular' else 'prismatic'} joint, ignored")
        return None
    drive = UsdPhysics.DriveAPI(prim, token)
    stiffness = float(drive.GetStiffnessAttr().Get() or 0.0) * gain_scale
    damping = float(drive.GetDampingAttr().Get() or 0.0) * gain_scale
    max_force = _limit(drive.GetMaxForceAttr().Get())
    max_force = None if max_force is None else max_force * force_scale
    kind = str(drive.GetTypeAttr().Get() or "force")
    if kind == "acceleration":
        notes.append(f"joint {joint!r}: an acceleration drive; its gains are used as force "
                     "gains (MuJoCo servos act by force)")
    for attr in ("TargetPosition", "TargetVelocity"):
        value = getattr(drive, f"Get{attr}Attr")().Get()
        if value:
            notes.append(f"joint {joint!r}: drive {attr[6:].lower()} target {value:g} not "
                         "applied (cosim's commands set the targets)")
    return Drive(stiffness, damping, max_force if max_force and max_force > 0 else None, kind)


def _frames(top, links: dict[str, Link], joints: dict[str, Joint], by_path, add_link,
            cache) -> None:
    """Plain Xforms below a link holding no geometry (sensor frames, massless links that
    urdf-usd-converter kept as Xforms) become frame links, fixed to the link above, and
    ``UsdGeom.Camera`` prims cameras on the link above."""
    from pxr import Usd, UsdGeom

    it = iter(_prims(top))
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
        if any(q.GetTypeName() in GPRIMS for q in _prims(prim)):
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


def _geometry(prim, link: Link, by_path: dict[str, str], cache, notes: list[str]) -> None:
    from pxr import UsdGeom, UsdPhysics

    it = iter(_prims(prim))
    next(it)
    for p in it:
        if str(p.GetPath()) in by_path:
            it.PruneChildren()
            continue
        kind = p.GetTypeName()
        if kind not in GPRIMS or "MjcSiteAPI" in api_schemas(p):  # a site: the link's frame
            continue
        collision = p.HasAPI(UsdPhysics.CollisionAPI)
        purpose = UsdGeom.Imageable(p).ComputePurpose()
        hidden = UsdGeom.Imageable(p).ComputeVisibility() == "invisible" and \
            _get(p, "mjc:group") is None  # mujoco-usd-converter hides MuJoCo's groups 3-5
        if not collision and (purpose in ("guide", "proxy") or hidden):
            continue
        if collision and _get(p, "physics:collisionEnabled", True) is False:
            continue
        world = _matrix(cache.GetLocalToWorldTransform(p))
        pose, scale = split_scale(world)
        geom = _shape(p, kind, pose, np.abs(scale), "collision" if collision else "visual",
                      link.name, notes)
        if geom is None:
            continue
        color = _get(p, "primvars:displayColor")
        if color is not None and len(color):
            opacity = _get(p, "primvars:displayOpacity")
            alpha = float(opacity[0]) if opacity is not None and len(opacity) else 1.0
            geom.rgba = (*(float(v) for v in color[0]), alpha)
        if collision:
            geom.friction = _friction(p)
        link.geoms.append(geom)


def _shape(p, kind: str, pose: np.ndarray, scale: np.ndarray, role: str, link: str,
           notes: list[str]) -> Geom | None:
    where = str(p.GetPath())
    if kind == "Cube":
        edge = float(_get(p, "size", 2.0))
        return Geom(role, "box", pose, tuple(float(v) for v in edge * scale), where)
    if kind == "Sphere":
        if np.ptp(scale) > 1e-9:
            notes.append(f"link {link!r}: sphere {where} scaled unevenly, its largest scale "
                         "used")
        return Geom(role, "sphere", pose, (float(_get(p, "radius", 1.0)) * float(scale.max()),),
                    where)
    if kind in ("Cylinder", "Capsule"):
        axis = str(_get(p, "axis", "Z"))
        turn = {"X": quat_matrix(math.cos(math.pi / 4), 0, math.sin(math.pi / 4), 0),
                "Y": quat_matrix(math.cos(math.pi / 4), -math.sin(math.pi / 4), 0, 0),
                "Z": np.eye(3)}[axis]
        along = "XYZ".index(axis)
        across = [s for i, s in enumerate(scale) if i != along]
        turned = pose.copy()
        turned[:3, :3] = pose[:3, :3] @ turn
        radius = float(_get(p, "radius", 1.0)) * float(max(across))
        height = float(_get(p, "height", 2.0)) * float(scale[along])
        return Geom(role, kind.lower(), turned, (radius, height), where)
    points = _get(p, "points")
    counts = _get(p, "faceVertexCounts")
    indices = _get(p, "faceVertexIndices")
    if points is None or counts is None or indices is None or len(points) < 4:
        notes.append(f"link {link!r}: mesh {where} has no points or faces, dropped")
        return None
    faces, at = [], 0
    indices = list(indices)
    for n in counts:
        faces += [(indices[at], indices[at + i], indices[at + i + 1]) for i in range(1, n - 1)]
        at += n
    return Geom(role, "mesh", pose, (), where, np.asarray(points, dtype=float) * scale,
                np.asarray(faces, dtype=np.int64))


def _friction(p) -> float | None:
    from pxr import UsdPhysics, UsdShade

    material, _ = UsdShade.MaterialBindingAPI(p).ComputeBoundMaterial("physics")
    if not material or not material.GetPrim().HasAPI(UsdPhysics.MaterialAPI):
        return None
    value = _get(material.GetPrim(), "physics:dynamicFriction")
    return None if value is None else float(value)


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
    for prim in _prims(top):
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


