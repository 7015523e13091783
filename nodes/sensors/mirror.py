"""A kinematic mirror of the physics world: same MJCF, positions copied from /cosim/world_state."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
from std_msgs.msg import Float64MultiArray

from nodes.physics.messages import world_version
from nodes.physics.world_events import model_at
from plan.events import EventSpec
from plan.robots import RobotsLayout


class WorldMirror:
    """Loads the world and poses it from the physics node's qpos (no dynamics run here).
    With scenario events (``plan.events``) the world it shows is the version each world
    state names (how many events are in it), so every node sees the objects physics has."""

    def __init__(self, world: Path | str, layout: RobotsLayout | None = None,
                 events: tuple[EventSpec, ...] = ()):
        self.world, self.layout, self.events = world, layout, tuple(events)
        self.version, self.label = 0, ""  # the world shown (nodes.physics.world_events)
        self._show(model_at(str(world), layout, self.events, 0))

    @classmethod
    def shared(cls, world: Path | str, layout: RobotsLayout | None = None,
               events: tuple[EventSpec, ...] = ()) -> WorldMirror:
        """The process's one mirror of this world: a swarm's sensor nodes packed into one
        process share it (a 1,000-robot world's MjData is about 19 MB). Sharing is safe
        because nodes of a process step one after another and each poses the mirror from
        its own input before it measures; an event's object is put in (once) by the first
        of them whose input shows it."""
        key = (str(world), layout, tuple(events))
        if key not in _SHARED:
            _SHARED[key] = cls(world, layout, events)
        return _SHARED[key]

    def _show(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        mujoco.mj_forward(model, self.data)
        self._posed_from: bytes | None = None

    def update(self, msg: Float64MultiArray) -> None:
        """Show the world version the message names, copy qpos out of it, then recompute
        frames (kinematics only; not again for the very qpos the mirror already shows)."""
        version, label = world_version(msg)
        if (version, label) != (self.version, self.label):
            if version > len(self.events) and not label:
                raise ValueError(f"/cosim/world_state shows world {self.world} with "
                                 f"{version} events applied; this node knows "
                                 f"{len(self.events)}")
            self._show(model_at(str(self.world), self.layout, self.events, version, label))
            self.version, self.label = version, label
        nq = self.model.nq
        dims = msg.layout.dim
        if not dims or dims[0].label != "qpos" or dims[0].size != nq or len(msg.data) < nq:
            got = (dims[0].label, dims[0].size) if dims else (None, len(msg.data))
            raise ValueError(f"/cosim/world_state does not match world {self.world} "
                             f"(version {version}): expected qpos of size {nq} first, "
                             f"got {got}")
        qpos = np.frombuffer(msg.data, dtype=np.float64, count=nq)
        posed_from = qpos.tobytes()
        if posed_from == self._posed_from:
            return
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)
        self._posed_from = posed_from


# (world, layout, events) -> the process's mirror of it (WorldMirror.shared)
_SHARED: dict[tuple[str, RobotsLayout | None, tuple[EventSpec, ...]], WorldMirror] = {}


def group_mask(groups: list[int]) -> np.ndarray:
    """The 6-entry geom group mask mj_ray/mjvOption take, with ``groups`` enabled."""
    mask = np.zeros(6, dtype=np.uint8)
    mask[list(groups)] = 1
    return mask
