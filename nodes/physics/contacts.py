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
        # counted[a][b]: whether a contact between geoms a and b is a collision. A table of
        # Python bools: the check runs every substep on a handful of contacts, where numpy's
        # per-call overhead cost ten times the lookups.
        self.counted: list[list[bool]] = ((robot[:, None] != robot[None, :])
                                          & ~floor[:, None] & ~floor[None, :]).tolist()
        self.touching: frozenset[tuple[int, int]] = frozenset()
        self.events = 0
        self._last_geoms = b""  # the contact list of the last check, as bytes

    def update(self, data: mujoco.MjData) -> None:
        """Look at the current contacts and count the pairs that are new."""
        n = data.ncon
        if n == 0:
            self.touching = frozenset()
            self._last_geoms = b""
            return
        geoms = data.contact.geom[:n]
        key = geoms.tobytes()
        if key == self._last_geoms:
            return  # the same contacts as one substep ago (wheels on the floor): nothing new
        self._last_geoms = key
        counted = self.counted
        now = frozenset((a, b) if a < b else (b, a) for a, b in geoms.tolist() if counted[a][b])
        if now:
            self.events += len(now - self.touching)
        self.touching = now
