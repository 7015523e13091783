"""The world's static geometry seen from above, read once from the MuJoCo model: what the
planner rasterises into its map, what the report picture draws and what the load-time
checks measure clearances against. One place, so they cannot disagree.

Static obstacles are the geoms welded to the world body that can collide and are not a
ground plane or height field. An upright cylinder, capsule or sphere is a circle of its
true radius; an upright box is its rotated rectangle; anything else (tilted shapes,
meshes, ellipsoids) is the convex hull of its bounding box's corners.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from plan.poses import yaw
from plan.rot3 import mat_vec, rotate_rows

ROUND = ("cylinder", "capsule")


@dataclass(frozen=True)
class Obstacle:
    """One static obstacle's footprint: a circle (``radius``) or a convex ``polygon``."""

    name: str
    geom: int
    kind: str  # the MuJoCo geom type in lower case: box, cylinder, capsule, sphere, mesh...
    centre: tuple[float, float]
    z_range: tuple[float, float]  # lowest and highest point
    radius: float | None = None  # circles
    polygon: np.ndarray | None = None  # (n, 2) counter-clockwise, for everything else
    visible: bool = True  # in a geom group drawn by default (0-2)

    @property
    def is_circle(self) -> bool:
        """Whether the footprint is a circle."""
        return self.radius is not None

    def distance(self, x: float, y: float) -> float:
        """Distance from (x, y) to the footprint (negative inside)."""
        if self.is_circle:
            return math.hypot(x - self.centre[0], y - self.centre[1]) - self.radius
        return polygon_distance(self.polygon, x, y)

    def distances(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """``distance`` at many points at once (arrays of one shape)."""
        if self.is_circle:
            return np.hypot(xs - self.centre[0], ys - self.centre[1]) - self.radius
        inside = polygon_edge_distances(self.polygon, xs, ys)
        return np.where(inside >= 0, -inside, polygon_outside_distances(self.polygon, xs, ys))

    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the footprint."""
        if self.is_circle:
            cx, cy = self.centre
            return cx - self.radius, cy - self.radius, cx + self.radius, cy + self.radius
        lo, hi = self.polygon.min(axis=0), self.polygon.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


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


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2D points, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted({(round(float(x), 9), round(float(y), 9)) for x, y in points})
    if len(pts) < 3:
        return np.array(pts)

    def half(seq):
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2 and _cross(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out[:-1]

    return np.array(half(pts) + half(reversed(pts)))


def _cross(o, a, b) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def polygon_edge_distances(polygon: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Signed distance of points to the line of each edge of a counter-clockwise convex
    polygon (positive inside); the minimum over edges is >= -h exactly for the points
    within h of the polygon, its corners taken square."""
    out = np.full(np.shape(xs), np.inf)
    n = len(polygon)
    for i in range(n):
        ax, ay = polygon[i]
        bx, by = polygon[(i + 1) % n]
        length = math.hypot(bx - ax, by - ay)
        if length == 0:
            continue
        d = ((bx - ax) * (ys - ay) - (by - ay) * (xs - ax)) / length
        np.minimum(out, d, out=out)
    return out


def polygon_outside_distances(polygon: np.ndarray, xs: np.ndarray, ys: np.ndarray
                              ) -> np.ndarray:
    """Distance of points to a polygon's boundary (its nearest edge segment)."""
    best = np.full(np.shape(xs), np.inf)
    n = len(polygon)
    for i in range(n):
        ax, ay = polygon[i]
        bx, by = polygon[(i + 1) % n]
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        t = 0.0 if length2 == 0 else np.clip(((xs - ax) * dx + (ys - ay) * dy) / length2, 0, 1)
        np.minimum(best, np.hypot(xs - ax - t * dx, ys - ay - t * dy), out=best)
    return best


def polygon_distance(polygon: np.ndarray, x: float, y: float) -> float:
    """Distance from (x, y) to a convex polygon (negative inside)."""
    inside = float(polygon_edge_distances(polygon, np.array(x), np.array(y)))
    if inside >= 0:
        return -inside
    best = math.inf
    n = len(polygon)
    for i in range(n):
        ax, ay = polygon[i]
        bx, by = polygon[(i + 1) % n]
        dx, dy = bx - ax, by - ay
        t = 0.0 if dx == dy == 0 else max(0.0, min(1.0, ((x - ax) * dx + (y - ay) * dy)
                                                    / (dx * dx + dy * dy)))
        best = min(best, math.hypot(x - ax - t * dx, y - ay - t * dy))
    return best


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


def robot_footprint_radius(model, base_body: str) -> float:
    """The radius of the circle around ``base_body``'s origin that holds every colliding geom
    of the robot (the body's whole subtree), seen from above, at the default pose."""
    import mujoco

    base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, base_body)
    if base < 0:
        raise ValueError(f"the world has no body {base_body!r}")
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    root = model.body_rootid[base]
    centre = data.xpos[base, :2]
    radius = 0.0
    for g in range(model.ngeom):
        if model.body_rootid[model.geom_bodyid[g]] != root:
            continue
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue
        offset = math.hypot(*(data.geom_xpos[g, :2] - centre))
        radius = max(radius, offset + float(model.geom_rbound[g]))
    return radius


def extent(obstacles: list[Obstacle]) -> tuple[float, float, float, float] | None:
    """(xmin, ymin, xmax, ymax) spanned by the obstacles (the world's walls), None if none."""
    if not obstacles:
        return None
    b = np.array([o.bounds() for o in obstacles])
    return float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max())


def place_problem(obstacles: list[Obstacle], x: float, y: float, radius: float,
                  z_band: tuple[float, float] = (0.02, 0.6)) -> str | None:
    """Why a robot of ``radius`` cannot stand at (x, y), or None: outside the world's extent,
    inside an obstacle, or closer to one than its radius (naming the obstacle)."""
    span = extent(obstacles)
    if span is not None and not (span[0] <= x <= span[2] and span[1] <= y <= span[3]):
        return (f"({x:g}, {y:g}) is outside the world, whose obstacles span x {span[0]:g} to "
                f"{span[2]:g} and y {span[1]:g} to {span[3]:g}")
    near = [(o.distance(x, y), o) for o in obstacles
            if o.z_range[1] >= z_band[0] and o.z_range[0] <= z_band[1]]
    if not near:
        return None
    gap, o = min(near, key=lambda item: item[0])
    if gap < 0:
        return f"({x:g}, {y:g}) is inside obstacle {o.name!r} ({o.kind})"
    if gap < radius:
        return (f"({x:g}, {y:g}) is {gap:.3f} m from obstacle {o.name!r} ({o.kind}), closer "
                f"than the robot's radius of {radius:.3f} m")
    return None
