"""The shapes of a USD robot's link: ``UsdGeom`` Cube, Sphere, Cylinder, Capsule and Mesh
prims under it, as collision (``PhysicsCollisionAPI``) or visual geometry, in metres with the
prims' scale applied, colour and the friction of a bound physics material."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from descriptions.usd_prims import api_schemas, get, matrix, prims, quat_matrix, split_scale

GPRIMS = ("Cube", "Sphere", "Cylinder", "Capsule", "Mesh")


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


def link_geometry(prim, link: str, by_path: dict[str, str], cache, notes: list[str]
                  ) -> list[Geom]:
    """The shapes under link prim ``prim`` (named ``link``), down to the next link prim (in
    ``by_path``): collisions (``PhysicsCollisionAPI``) and visuals (not guide or proxy, not
    hidden), with colour and physics-material friction; a shape cosim cannot read is a note."""
    from pxr import UsdGeom, UsdPhysics

    out = []
    it = iter(prims(prim))
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
            get(p, "mjc:group") is None  # mujoco-usd-converter hides MuJoCo's groups 3-5
        if not collision and (purpose in ("guide", "proxy") or hidden):
            continue
        if collision and get(p, "physics:collisionEnabled", True) is False:
            continue
        world = matrix(cache.GetLocalToWorldTransform(p))
        pose, scale = split_scale(world)
        geom = _shape(p, kind, pose, np.abs(scale), "collision" if collision else "visual",
                      link, notes)
        if geom is None:
            continue
        color = get(p, "primvars:displayColor")
        if color is not None and len(color):
            opacity = get(p, "primvars:displayOpacity")
            alpha = float(opacity[0]) if opacity is not None and len(opacity) else 1.0
            geom.rgba = (*(float(v) for v in color[0]), alpha)
        if collision:
            geom.friction = _friction(p)
        out.append(geom)
    return out


def _shape(p, kind: str, pose: np.ndarray, scale: np.ndarray, role: str, link: str,
           notes: list[str]) -> Geom | None:
    where = str(p.GetPath())
    if kind == "Cube":
        edge = float(get(p, "size", 2.0))
        return Geom(role, "box", pose, tuple(float(v) for v in edge * scale), where)
    if kind == "Sphere":
        if np.ptp(scale) > 1e-9:
            notes.append(f"link {link!r}: sphere {where} scaled unevenly, its largest scale "
                         "used")
        return Geom(role, "sphere", pose, (float(get(p, "radius", 1.0)) * float(scale.max()),),
                    where)
    if kind in ("Cylinder", "Capsule"):
        axis = str(get(p, "axis", "Z"))
        turn = {"X": quat_matrix(math.cos(math.pi / 4), 0, math.sin(math.pi / 4), 0),
                "Y": quat_matrix(math.cos(math.pi / 4), -math.sin(math.pi / 4), 0, 0),
                "Z": np.eye(3)}[axis]
        along = "XYZ".index(axis)
        across = [s for i, s in enumerate(scale) if i != along]
        turned = pose.copy()
        turned[:3, :3] = pose[:3, :3] @ turn
        radius = float(get(p, "radius", 1.0)) * float(max(across))
        height = float(get(p, "height", 2.0)) * float(scale[along])
        return Geom(role, kind.lower(), turned, (radius, height), where)
    points = get(p, "points")
    counts = get(p, "faceVertexCounts")
    indices = get(p, "faceVertexIndices")
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
    value = get(material.GetPrim(), "physics:dynamicFriction")
    return None if value is None else float(value)
