"""Reading values and poses off USD prims for the robot reader: authored attribute values,
limits, quaternions and 4x4 poses (column vectors, scale split off, rotations snapped to the
right angles float32 misses), traversal into instances, applied schema names."""

from __future__ import annotations

import math

import numpy as np

UNLIMITED = 1e17  # |limit| at or above this (or inf) is no limit


def matrix(m) -> np.ndarray:
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


def snapped_pose(t: np.ndarray) -> np.ndarray:
    """A 4x4 pose with its rotation snapped (``snapped``)."""
    t = t.copy()
    t[:3, :3] = snapped(t[:3, :3])
    return t


def matrix_quat(r: np.ndarray) -> tuple[float, float, float, float]:
    """The quaternion (w, x, y, z) of a rotation matrix."""
    import mujoco

    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(r, dtype=float).ravel())
    return tuple(float(v) for v in q)


def quat(q) -> tuple[float, float, float, float]:
    """A Gf quaternion as (w, x, y, z)."""
    return (float(q.GetReal()), *(float(v) for v in q.GetImaginary()))


def get(prim, name: str, default=None):
    """The authored value of attribute ``name`` (``default`` when it has none)."""
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasAuthoredValue():
        return default
    return attr.Get()


def limit(value) -> float | None:
    """A limit as a float; None when absent, infinite or at least UNLIMITED in size."""
    return None if value is None or not math.isfinite(value) or abs(value) >= UNLIMITED \
        else float(value)


def prims(prim):
    """Every prim from ``prim`` down, into instances too (Isaac's importer makes its meshes
    instanceable: their colliders live in the instances' prototypes)."""
    from pxr import Usd

    return Usd.PrimRange(prim, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate))


def api_schemas(prim) -> set[str]:
    """The API schemas applied to ``prim``, registered or not (mujoco-usd-converter's
    ``MjcSiteAPI`` is unknown to usd-core alone)."""
    names = {str(s) for s in prim.GetAppliedSchemas()}
    listed = prim.GetMetadata("apiSchemas")
    if listed is not None:
        names |= {str(s) for s in listed.GetAddedOrExplicitItems()}
    return {n.split(":")[0] for n in names}
