"""2D and 3D lidar by ray casting (mujoco.mj_multiRay) from a site on the robot.

Rays are cast against the geom groups listed in the parameters only; robot geoms live in
group 3 so the robot never sees itself. A beam with no hit within range_max reads +inf and
one that hits closer than range_min reads -inf (REP-117). The sweep is instantaneous:
every beam sees the world at the tick's time (time_increment = 0).
"""

from __future__ import annotations

import array
import math

import mujoco
import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from sensor_msgs.msg import LaserScan, PointCloud2, PointField

from nodes.physics.world import named_id
from nodes.sensors.mirror import WorldMirror, group_mask
from plan.rot3 import rotate_rows, row_dots


class LidarParams(BaseModel):
    """A planar scanner: beams over a field of view (radians), range limits, noise (m)."""

    model_config = ConfigDict(extra="forbid")
    site: str | None = Field(None, description="the site it casts from; default: the robot "
                             "model's lidar (descriptions.robot_reader)")
    frame_id: str | None = Field(None, description="its frame; default: the robot model's")
    beams: int = Field(360, ge=1)
    fov: float = Field(2 * math.pi, gt=0, le=2 * math.pi)
    range_min: float = Field(0.12, ge=0)
    range_max: float = Field(12.0, gt=0)
    noise_stddev: float = Field(0.01, ge=0)
    geom_groups: list[int] = [0, 1, 2]


class PointCloudParams(LidarParams):
    """A multi-channel scanner: ``channels`` rings spread over ``vertical_fov`` (radians)."""

    channels: int = Field(16, ge=1)
    vertical_fov: float = Field(0.5236, ge=0, lt=math.pi)


def scan_angles(beams: int, fov: float) -> tuple[float, float, np.ndarray]:
    """(angle_min, increment, angles): a full circle does not repeat its first beam."""
    full = fov >= 2 * math.pi - 1e-9
    inc = fov / beams if full or beams == 1 else fov / (beams - 1)
    start = -math.pi if full else -fov / 2
    return start, inc, start + inc * np.arange(beams)


def robot_in(model: mujoco.MjModel, site: str) -> bool:
    """Whether ``site`` is in ``model`` now; a robot's that enters the run later is not
    until it does (its sensor node is dormant until then: ``plan.schedule``)."""
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site) >= 0 or "/" not in site


class RayCaster:
    """Casts a fixed bundle of rays (in the site frame) from a site of the mirrored world,
    in one mj_multiRay call; against ``target`` (a model and data: a swarm's arena without
    its robots, ``nodes.sensors.others.StaticWorld``) when given, else the mirror itself."""

    def __init__(self, mirror: WorldMirror, params: LidarParams, local_dirs: np.ndarray,
                 others=None, target=None):
        self.mirror = mirror
        self.others = others  # nodes.sensors.others.OtherRobots: robots seen as discs
        self.target = target if target is not None else mirror
        self.params = params
        self._site_model = None  # the model ``site`` is an id of (a robot that enters or
        # leaves moves every id after it): looked up again when the mirror shows another
        self.site = self._site() if robot_in(mirror.model, params.site) else -1
        self.local = np.ascontiguousarray(local_dirs, dtype=np.float64)
        self.n = len(self.local)
        self.groups = group_mask(params.geom_groups)
        self.geomid = np.zeros(self.n, dtype=np.int32)
        self.dist = np.zeros(self.n, dtype=np.float64)
        self.normal = np.zeros(3 * self.n, dtype=np.float64)

    def _site(self) -> int:
        self._site_model = self.mirror.model
        return named_id(self.mirror.model, mujoco.mjtObj.mjOBJ_SITE, self.params.site)

    def cast(self, rng: np.random.Generator) -> np.ndarray:
        """Noisy ranges (inf = no return, -inf = closer than range_min) per ray."""
        if self.mirror.model is not self._site_model:
            self.site = self._site()
        d = self.mirror.data
        vec = rotate_rows(self.local, d.site_xmat[self.site]).ravel()
        p = self.params
        origin = d.site_xpos[self.site].copy()
        mujoco.mj_multiRay(self.target.model, self.target.data, origin, vec,
                           self.groups, 1, -1, self.geomid, self.dist, self.normal, self.n,
                           p.range_max)
        dist = self.dist
        if self.others is not None:
            dist = self.others.nearer(d, origin, vec.reshape(-1, 3), dist, p.range_max)
        noise = rng.normal(0.0, p.noise_stddev, self.n) if p.noise_stddev > 0 else 0.0
        r = dist + noise
        hit = (dist >= 0) & (r <= p.range_max)
        return np.where(hit, np.where(r < p.range_min, -np.inf, r), np.inf)


class Lidar2D:
    """The planar scanner publishing sensor_msgs/LaserScan."""

    def __init__(self, mirror: WorldMirror, params: LidarParams, period_ns: int,
                 others=None, target=None):
        self.params = params
        self.angle_min, self.inc, angles = scan_angles(params.beams, params.fov)
        dirs = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
        self.caster = RayCaster(mirror, params, dirs, others, target)
        self.scan_time = period_ns / 1e9

    def measure(self, rng: np.random.Generator) -> LaserScan:
        """One scan of the mirrored world."""
        p = self.params
        msg = LaserScan()
        msg.header.frame_id = p.frame_id
        msg.angle_min = self.angle_min
        msg.angle_max = self.angle_min + self.inc * (p.beams - 1)
        msg.angle_increment = self.inc
        msg.time_increment = 0.0
        msg.scan_time = self.scan_time
        msg.range_min = p.range_min
        msg.range_max = p.range_max
        msg.ranges = array.array("f", self.caster.cast(rng).astype(np.float32).tobytes())
        return msg


class Lidar3D:
    """The multi-channel scanner publishing sensor_msgs/PointCloud2 (x y z intensity, float32).

    Points are in the sensor frame; beams without a return are left out (is_dense = true).
    Intensity is the cosine of the incidence angle, a cheap stand-in for reflectivity.
    """

    FIELDS = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
              for i, n in enumerate("x y z intensity".split())]

    def __init__(self, mirror: WorldMirror, params: PointCloudParams, others=None,
                 target=None):
        self.params = params
        _, _, az = scan_angles(params.beams, params.fov)
        el = (np.linspace(-params.vertical_fov / 2, params.vertical_fov / 2, params.channels)
              if params.channels > 1 else np.zeros(1))
        e, a = np.meshgrid(el, az, indexing="ij")
        self.dirs = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)],
                             axis=-1).reshape(-1, 3)
        self.caster = RayCaster(mirror, params, self.dirs, others, target)

    def measure(self, rng: np.random.Generator) -> PointCloud2:
        """One sweep of the mirrored world as an unorganised cloud."""
        r = self.caster.cast(rng)
        ok = np.isfinite(r)
        pts = self.dirs[ok] * r[ok, None]
        rot = self.caster.mirror.data.site_xmat[self.caster.site]
        normals = self.caster.normal.reshape(-1, 3)[ok]
        intensity = np.abs(row_dots(normals, rotate_rows(self.dirs[ok], rot)))
        cloud = np.empty((len(pts), 4), dtype=np.float32)
        cloud[:, :3] = pts
        cloud[:, 3] = intensity
        msg = PointCloud2()
        msg.header.frame_id = self.params.frame_id
        msg.height = 1
        msg.width = len(pts)
        msg.fields = self.FIELDS
        msg.is_bigendian = False
        msg.point_step = 16
        msg.row_step = 16 * len(pts)
        msg.data = cloud.tobytes()
        msg.is_dense = True
        return msg
