"""A kinematic mirror of the physics world: same MJCF, positions copied from /cosim/world_state."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
from std_msgs.msg import Float64MultiArray

from nodes.physics.world import load_model
from plan.robots import RobotsLayout


class WorldMirror:
    """Loads the world and poses it from the physics node's qpos (no dynamics run here)."""

    def __init__(self, world: Path | str, layout: RobotsLayout | None = None):
        self.world = world
        self.model = load_model(world, layout)
        self.data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, self.data)
        self._posed_from: bytes | None = None

    @classmethod
    def shared(cls, world: Path | str, layout: RobotsLayout | None = None) -> WorldMirror:
        """The process's one mirror of this world: a swarm's sensor nodes packed into one
        process share it (a 1,000-robot world's MjData is about 19 MB). Sharing is safe
        because nodes of a process step one after another and each poses the mirror from
        its own input before it measures."""
        key = (str(world), layout)
        if key not in _SHARED:
            _SHARED[key] = cls(world, layout)
        return _SHARED[key]

    def update(self, msg: Float64MultiArray) -> None:
        """Copy qpos out of a world-state message, then recompute frames (kinematics only;
        not again for the very qpos the mirror already shows)."""
        nq = self.model.nq
        dims = msg.layout.dim
        if not dims or dims[0].label != "qpos" or dims[0].size != nq or len(msg.data) < nq:
            got = (dims[0].label, dims[0].size) if dims else (None, len(msg.data))
            raise ValueError(f"/cosim/world_state does not match world {self.world}: expected "
                             f"qpos of size {nq} first, got {got}")
        qpos = np.frombuffer(msg.data, dtype=np.float64, count=nq)
        posed_from = qpos.tobytes()
        if posed_from == self._posed_from:
            return
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)
        self._posed_from = posed_from


# (world, layout) -> the process's mirror of it (WorldMirror.shared)
_SHARED: dict[tuple[str, RobotsLayout | None], WorldMirror] = {}


def group_mask(groups: list[int]) -> np.ndarray:
    """The 6-entry geom group mask mj_ray/mjvOption take, with ``groups`` enabled."""
    mask = np.zeros(6, dtype=np.uint8)
    mask[list(groups)] = 1
    return mask
