"""The world's static geometry seen from above, read once from the MuJoCo model: what the
planner rasterises into its map, what the report picture draws and what the load-time
checks measure clearances against. One place, so they cannot disagree.

Static obstacles are the geoms welded to the world body that can collide and are not a
ground plane or height field. An upright cylinder, capsule or sphere is a circle of its
true radius; an upright box is its rotated rectangle; anything else (tilted shapes,
meshes, ellipsoids) is the convex hull of its bounding box's corners. The footprints and
the pure geometry over them (distances, where a robot fits) are ``plan.obstacles``.
"""

from __future__ import annotations

import math

import numpy as np

from plan.obstacles import Obstacle, convex_hull
from plan.poses import yaw
from plan.rot3 import mat_vec, rotate_rows

ROUND = ("cylinder", "capsule")


def geom_kind(model, g: int) -> str:
    """'box', 'cylinder', ... for geom ``g`` (compared as text: a numpy integer is never
    'in' a tuple of MuJoCo's enum members, which hid cylinders from the planner once)."""
    import mujoco

    return mujoco.mjtGeom(int(model.geom_type[g])).name.removeprefix("mjGEOM_").lower()


def floor_mask(model) -> np.ndarray:
    """Boolean mask over geoms: the ground planes and height fields."""
    import mujoco

    return np.isin(model.geom_type, [int(mujoco.mjtGeom.mjGEOM_PLANE),
                                     int(mujoco.mjtGeom.mjGEOM_HFIELD)])


def static_mask(model) -> np.ndarray:
    """Boolean mask over geoms that never move and can collide: the map's obstacles."""
    welded = model.body_weldid[model.geom_bodyid] == 0
    collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    return welded & collides & ~floor_mask(model)


def static_obstacles(model) -> list[Obstacle]:
    """Every static obstacle of ``model`` at its default pose."""
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return [obstacle(model, data, int(g)) for g in np.flatnonzero(static_mask(model))]


def obstacle(model, data, g: int) -> Obstacle:
    """Geom ``g``'s footprint at the pose in ``data``."""
    kind = geom_kind(model, g)
    pos = data.geom_xpos[g]
    rot = data.geom_xmat[g].reshape(3, 3)
    size = model.geom_size[g]
    upright = abs(rot[2, 2]) > 0.999
    half = mat_vec(np.abs(rot), _local_half_extents(model, g, kind))
    name = model.geom(g).name or f"geom {g}"
    common = dict(name=name, geom=g, kind=kind, centre=(float(pos[0]), float(pos[1])),
                  z_range=(float(pos[2] - half[2]), float(pos[2] + half[2])),
                  visible=bool(model.geom_group[g] <= 2))
    if kind == "sphere" or (kind in ROUND and upright):
        return Obstacle(radius=float(size[0]), **common)
    if kind == "box":
        centre, extent = np.zeros(3), size
    else:
        centre, extent = model.geom_aabb[g][:3], model.geom_aabb[g][3:]
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    points = pos + rotate_rows(centre + corners * extent, rot)
    return Obstacle(polygon=convex_hull(points[:, :2]), **common)


def _local_half_extents(model, g: int, kind: str) -> np.ndarray:
    s = model.geom_size[g]
    if kind == "box":
        return s.copy()
    if kind == "cylinder":
        return np.array([s[0], s[0], s[1]])
    if kind == "capsule":
        return np.array([s[0], s[0], s[1] + s[0]])
    if kind == "sphere":
        return np.array([s[0], s[0], s[0]])
    return np.abs(model.geom_aabb[g][:3]) + model.geom_aabb[g][3:]


def site_offset(model, name: str) -> tuple[float, float, float]:
    """(x, y, yaw) of a site in its body's frame; zero when the world has no such site.

    The body is taken to be the odometry's base frame: true for the laser on base_link.
    """
    import mujoco

    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid < 0:
        return 0.0, 0.0, 0.0
    w, x, y, z = model.site_quat[sid]
    return float(model.site_pos[sid][0]), float(model.site_pos[sid][1]), yaw(w, x, y, z)


def _posed(model):
    """An MjData of ``model`` at its default pose (kinematics only), made once for the last
    model asked: a swarm world asks once per robot, and posing the whole world each time
    made reading a thousand robots take seconds."""
    import mujoco

    held = _POSED.get("last")
    if held is None or held[0] is not model:
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        held = _POSED["last"] = (model, data)
    return held[1]


_POSED: dict[str, tuple] = {}
"""_posed's last (model, data): the model is kept with it."""


def robot_footprint_radius(model, base_body: str) -> float:
    """The radius of the circle around ``base_body``'s origin that holds every colliding geom
    of the robot (the body's whole subtree), seen from above, at the default pose."""
    import mujoco

    base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, base_body)
    if base < 0:
        raise ValueError(f"the world has no body {base_body!r}")
    data = _posed(model)
    root = model.body_rootid[base]
    centre = data.xpos[base, :2]
    radius = 0.0
    own = (model.body_rootid[model.geom_bodyid] == root) & (
        (model.geom_contype != 0) | (model.geom_conaffinity != 0))
    for g in np.flatnonzero(own).tolist():  # this robot's colliding geoms, not the swarm's
        offset = math.hypot(*(data.geom_xpos[g, :2] - centre))
        radius = max(radius, offset + float(model.geom_rbound[g]))
    return radius
