"""A USD robot's joints: revolute, prismatic and fixed ``UsdPhysics`` joints read into plain
data (the pivot and axis in the child's frame, limits in radians or metres, drives in SI),
``MjcActuator`` prims as drives, names made unique, and the joints ordered from the root."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from descriptions.description_error import DescriptionError
from descriptions.usd_prims import get, limit, prims, quat, quat_matrix, snapped

WORLD = "world"  # the parent of a joint that holds the robot to the world
ONE_SIDED = 1e6  # m: where a prismatic joint limited on one side only is limited on the other

JOINT_TYPES = {"PhysicsRevoluteJoint": "revolute", "PhysicsPrismaticJoint": "prismatic",
               "PhysicsFixedJoint": "fixed"}


@dataclass
class Drive:
    """A ``PhysicsDriveAPI``: stiffness and damping in SI (per radian for an angular
    drive), the force limit (None: unlimited) and its type."""

    stiffness: float
    damping: float
    max_force: float | None
    kind: str = "force"


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


def named_joints(description: str, found: list[Joint], notes: list[str]) -> dict[str, Joint]:
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


def misplaced(poses: dict[str, np.ndarray], joints: dict[str, Joint]) -> list[str]:
    """Joints whose two frames (``localPos0`` on the parent, ``localPos1`` on the child) are
    more than 1 mm apart where the links' prims stand (``poses``: link -> 4x4): the bodies are
    placed by their prims, as authored, and the joint turns the child about its own frame."""
    off = []
    for j in joints.values():
        if j.parent == WORLD or j.anchor is None or j.parent not in poses:
            continue
        a = poses[j.parent] @ np.array([*j.anchor, 1.0])
        b = poses[j.child] @ np.array([*j.pivot, 1.0])
        if np.linalg.norm(a - b) > 1e-3:
            off.append(f"{j.name} ({np.linalg.norm(a - b) * 1000:.1f} mm)")
    return [f"joint frames apart where the bodies stand, bodies kept where their prims put "
            f"them: {', '.join(off)}"] if off else []


def tree_order(joints: dict[str, Joint], root: str) -> dict[str, Joint]:
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


def read_joint(prim, kind: str, parent: str, child: str, units: tuple[float, float],
               notes: list[str], name: str) -> Joint:
    """Joint prim ``prim`` of ``kind`` between links ``parent`` and ``child``, named ``name``,
    in SI from the stage's ``units`` (metres, kilograms per unit): limits, drive (a
    ``PhysicsDriveAPI`` of the joint's kind), effort, velocity limit and damping."""
    meters, kilograms = units
    pivot = tuple(float(v) * meters for v in (get(prim, "physics:localPos1") or (0, 0, 0)))
    rot1 = get(prim, "physics:localRot1")
    r1 = np.eye(3) if rot1 is None else snapped(quat_matrix(*quat(rot1)))
    axis_token = str(get(prim, "physics:axis", "X"))
    unit = {"X": (1.0, 0, 0), "Y": (0, 1.0, 0), "Z": (0, 0, 1.0)}.get(axis_token, (1.0, 0, 0))
    axis = tuple(float(round(v, 12)) + 0.0 for v in r1 @ np.array(unit))
    pos0 = get(prim, "physics:localPos0")
    anchor = None if pos0 is None else tuple(float(v) * meters for v in pos0)
    joint = Joint(name, str(prim.GetPath()), kind, parent, child, pivot, axis, anchor)
    if kind == "fixed":
        return joint
    degrees = kind == "revolute"
    # to SI: a force is kg * unit / s^2, a torque kg * unit^2 / s^2; angles in degrees
    gain_scale = kilograms * (180.0 / math.pi * meters ** 2 if degrees else 1.0)  # per rad
    force_scale = kilograms * (meters ** 2 if degrees else meters)
    speed_scale = math.pi / 180.0 if degrees else meters
    lower = limit(get(prim, "physics:lowerLimit"))
    upper = limit(get(prim, "physics:upperLimit"))
    unit = math.radians(1.0) if degrees else meters
    lower = None if lower is None else lower * unit
    upper = None if upper is None else upper * unit
    if (lower is None) != (upper is None):  # URDF has no one-sided limit
        side = "lower" if lower is not None else "upper"
        if degrees:
            notes.append(f"joint {name!r}: only a {side} limit: read as continuous")
            lower = upper = None
        else:
            notes.append(f"joint {name!r}: only a {side} limit: the other side at "
                         f"{ONE_SIDED:g} m")
            lower = -ONE_SIDED if lower is None else lower
            upper = ONE_SIDED if upper is None else upper
    joint.lower, joint.upper = lower, upper
    joint.drive = _drive(prim, "angular" if degrees else "linear", gain_scale, force_scale,
                         name, notes)
    effort = get(prim, "urdf:limit:effort", get(prim, "mjc:actuatorfrcrange:max"))
    if joint.drive is not None and joint.drive.max_force is not None:
        joint.effort = joint.drive.max_force
    elif effort is not None and effort > 0:
        joint.effort = float(effort)
    for attr, scale in (("physxJoint:maxJointVelocity", speed_scale),
                        ("newton:velocityLimit", speed_scale),
                        ("urdf:limit:velocity", 1.0)):
        value = limit(get(prim, attr))
        if value is not None and value > 0:
            joint.velocity = value * scale
            break
    for attr in ("physxJoint:jointFriction", "physxJoint:armature", "mjc:frictionloss",
                 "mjc:armature"):
        if get(prim, attr):
            notes.append(f"joint {name!r}: {attr} {get(prim, attr):g} not read")
    for attr, scale in (("newton:damping", gain_scale), ("mjc:damping", 1.0)):
        value = get(prim, attr)
        if value is not None and value > 0:
            joint.damping = float(value) * scale
            break
    return joint


def mjc_actuators(description: str, top, joints: dict[str, Joint], notes: list[str]) -> None:
    """mujoco-usd-converter's ``MjcActuator`` prims as drives of the joints they target: a
    position servo (gain kp, bias [0, -kp, -kv]), a velocity servo (gain kv, bias [0, 0,
    -kv]) or a motor; ``mjc:forceRange`` the force limit. DescriptionError for a gear other
    than 1 (its gains and limits would be the actuator's, not the joint's)."""

    by_prim = {j.prim: j for j in joints.values()}
    for prim in prims(top):
        if prim.GetTypeName() != "MjcActuator":
            continue
        targets = prim.GetRelationship("mjc:target").GetTargets() \
            if prim.GetRelationship("mjc:target") else []
        joint = by_prim.get(str(targets[0])) if targets else None
        if joint is None or joint.kind == "fixed":
            notes.append(f"actuator {prim.GetName()!r}: its mjc:target is no moving joint, "
                         "ignored")
            continue
        gear = float((list(get(prim, "mjc:gear") or [1.0]) + [1.0])[0])
        if gear != 1.0:
            raise DescriptionError(
                description, f"actuator {prim.GetName()!r} has mjc:gear {gear:g}: cosim "
                "reads a drive's gains and force limit as the joint's",
                prim=str(prim.GetPath()),
                fix="a gear of 1 (scale mjc:gainPrm, mjc:biasPrm and mjc:forceRange by the "
                    "gear instead)")
        gain = list(get(prim, "mjc:gainPrm") or [1.0])
        bias = list(get(prim, "mjc:biasPrm") or [0.0, 0.0, 0.0]) + [0.0, 0.0, 0.0]
        affine = str(get(prim, "mjc:biasType", "none")) == "affine"
        kp = float(gain[0]) if affine and bias[1] < 0 else 0.0
        kv = -float(bias[2]) if affine and bias[2] < 0 else 0.0
        high = get(prim, "mjc:forceRange:max")
        limited = str(get(prim, "mjc:forceLimited", "false")) == "true"
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
    max_force = limit(drive.GetMaxForceAttr().Get())
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
