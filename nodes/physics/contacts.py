"""Collision events between the robot and the world (the floor does not count)."""

from __future__ import annotations

import mujoco
import numpy as np


class CollisionCounter:
    """Counts collision events: a (robot geom, other geom) pair that starts touching.

    The contact set is checked after every physics substep; a pair that was not in contact
    at the previous substep and is now counts once, however long it stays in contact.
    Contacts with the floor (planes, height fields) and within the robot are ignored.
    """

    def __init__(self, robot: np.ndarray, floor: np.ndarray):
        self.robot = robot
        self.ignored = floor
        self.touching: frozenset[tuple[int, int]] = frozenset()
        self.events = 0

    def update(self, data: mujoco.MjData) -> None:
        """Look at the current contacts and count the pairs that are new."""
        n = data.ncon
        if n == 0:
            self.touching = frozenset()
            return
        g1 = data.contact.geom1[:n]
        g2 = data.contact.geom2[:n]
        hit = (self.robot[g1] != self.robot[g2]) & ~self.ignored[g1] & ~self.ignored[g2]
        if not hit.any():
            self.touching = frozenset()
            return
        lo = np.minimum(g1[hit], g2[hit]).tolist()
        hi = np.maximum(g1[hit], g2[hit]).tolist()
        now = frozenset(zip(lo, hi, strict=True))
        self.events += len(now - self.touching)
        self.touching = now
