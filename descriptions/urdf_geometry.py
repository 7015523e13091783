"""Numbers read from a compiled robot's geometry: points on its collision geoms, a wheel's
radius about its joint axis, the two wheels' separation, the footprint's radius."""

from __future__ import annotations

import math

import mujoco
import numpy as np

GEOM = mujoco.mjtGeom


def _sphere_dirs(n: int = 96) -> np.ndarray:
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = math.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], 1)


def geom_points(model: mujoco.MjModel, data: mujoco.MjData, gid: int) -> np.ndarray:
    """Points (n, 3) in the world on the surface of geom ``gid`` (after mj_kinematics):
    a mesh's vertices, a box's corners, rims and caps of the round shapes."""
    kind, size = model.geom_type[gid], model.geom_size[gid]
    a = np.linspace(0, 2 * math.pi, 64, endpoint=False)
    if kind == GEOM.mjGEOM_MESH:
        mid = model.geom_dataid[gid]
        adr, num = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        local = model.mesh_vert[adr:adr + num].astype(float)
    elif kind == GEOM.mjGEOM_BOX:
        local = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * size
    elif kind == GEOM.mjGEOM_CYLINDER:
        rim = np.stack([size[0] * np.cos(a), size[0] * np.sin(a), np.zeros_like(a)], 1)
        local = np.concatenate([rim + [0, 0, size[1]], rim - [0, 0, size[1]]])
    elif kind == GEOM.mjGEOM_CAPSULE:
        s = _sphere_dirs() * size[0]
        local = np.concatenate([s + [0, 0, size[1]], s - [0, 0, size[1]]])
    elif kind in (GEOM.mjGEOM_SPHERE, GEOM.mjGEOM_ELLIPSOID):
        local = _sphere_dirs() * (size[0] if kind == GEOM.mjGEOM_SPHERE else size)
    else:
        return np.zeros((0, 3))
    return data.geom_xpos[gid] + local @ data.geom_xmat[gid].reshape(3, 3).T


def wheel_radius(model: mujoco.MjModel, data: mujoco.MjData, joint: int,
                 geoms: list[int]) -> float:
    """The largest distance of the wheel's collision geom points from its joint axis."""
    anchor, axis = data.xanchor[joint], data.xaxis[joint]
    pts = np.concatenate([geom_points(model, data, g) for g in geoms]) - anchor
    radial = pts - np.outer(pts @ axis, axis)
    return float(np.max(np.linalg.norm(radial, axis=1))) if len(pts) else 0.0


def wheel_separation(model: mujoco.MjModel, data: mujoco.MjData, left: int, right: int,
                     left_geoms: list[int], right_geoms: list[int]) -> float:
    """The distance along the left wheel's axis between the two wheels' centres (the
    middle of each wheel's collision geometry, its joint anchor when it has none)."""
    def centre(joint: int, geoms: list[int]) -> np.ndarray:
        if not geoms:
            return data.xanchor[joint]
        pts = np.concatenate([geom_points(model, data, g) for g in geoms])
        return (pts.min(axis=0) + pts.max(axis=0)) / 2
    gap = centre(left, left_geoms) - centre(right, right_geoms)
    return float(abs(gap @ data.xaxis[left]))


def footprint_radius(model: mujoco.MjModel, data: mujoco.MjData, root_body: int,
                     geoms: list[int]) -> float:
    """The radius about the root body's origin, in its xy plane, of every collision geom."""
    if not geoms:
        return 0.0
    pts = np.concatenate([geom_points(model, data, g) for g in geoms]) - data.xpos[root_body]
    local = pts @ data.xmat[root_body].reshape(3, 3)
    return float(np.max(np.hypot(local[:, 0], local[:, 1])))
