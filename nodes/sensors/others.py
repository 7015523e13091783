"""What one robot's sensors see of the other robots of a swarm.

Every robot's geoms are in geom group 3, which the lidar does not cast against (so it never
sees its own body), and the description's lidar plane passes above the chassis anyway. In
a swarm the other robots must show in the scan, so the lidar adds them as what the planner
and the placement treat them as: an upright cylinder of the robot's footprint radius (every
colliding geom of it, seen from above) around each other robot's base, from floor to sky.
A beam returns the nearer of its MuJoCo hit and the first such cylinder it meets.
"""

from __future__ import annotations

import mujoco
import numpy as np

from descriptions.robot_model import RobotModel
from plan.robots import RobotsLayout, prefixed


class OtherRobots:
    """The other robots' bases and their footprint radius, for ray casting as cylinders."""

    def __init__(self, model: mujoco.MjModel, layout: RobotsLayout, robot: RobotModel):
        bodies = [prefixed(r, layout.base_body) for r in layout.names if r != robot.name]
        self.bodies = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b)
                                for b in bodies], dtype=np.int64)
        self.radius = robot.footprint_radius

    def nearer(self, data: mujoco.MjData, origin: np.ndarray, dirs: np.ndarray,
               dist: np.ndarray, range_max: float) -> np.ndarray:
        """``dist`` (MuJoCo's: -1 for no hit) with each beam shortened to the first other
        robot it meets within ``range_max``."""
        if self.bodies.size == 0:
            return dist
        centres = data.xpos[self.bodies, :2] - origin[:2]
        near = np.hypot(centres[:, 0], centres[:, 1]) <= range_max + self.radius
        if not near.any():
            return dist
        c = centres[near]  # (k, 2)
        d = dirs[:, :2]  # (n, 2): the horizontal part of each beam (unit length in 3D)
        # element by element, no matrix products: the same bits on every CPU
        a = (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])[:, None]  # (n, 1)
        b = d[:, :1] * c[:, 0] + d[:, 1:2] * c[:, 1]  # (n, k): beam . centre
        cc = (c[:, 0] * c[:, 0] + c[:, 1] * c[:, 1])[None, :] - self.radius ** 2
        disc = b * b - a * cc
        with np.errstate(invalid="ignore", divide="ignore"):
            t = (b - np.sqrt(disc)) / a
        t = np.where((disc >= 0) & (t > 0) & (a > 1e-12), t, np.inf).min(axis=1)
        hit = t <= range_max
        if not hit.any():
            return dist
        return np.where(hit & ((dist < 0) | (t < dist)), t, dist)
