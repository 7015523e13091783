"""A world that changes while the run goes: the scenario's events (``plan.events``) applied
at their ticks, the same in every node that holds a copy of the world.

The physics node keeps the world's MjSpec and recompiles it at each event
(``LiveWorld``: MjSpec.recompile keeps the state of every body already there, bit for
bit); a mirror (the sensors') asks for the model of a version, the number of events
applied (``model_at``), which the physics node publishes with every world state
(``nodes.physics.messages.world_version``), so a node that reaches the tick first, or
trails, poses the world that its input shows.
"""

from __future__ import annotations

import functools
from pathlib import Path

import mujoco
import numpy as np

from descriptions.world_edits import apply_event, world_spec
from descriptions.worldfile import compile_world
from nodes.physics.world import load_model
from plan.events import EventSpec, applied_by
from plan.robots import RobotsLayout


class LiveWorld:
    """The physics node's world: its spec, the model compiled from it, and how many of
    the scenario's events are in it."""

    def __init__(self, world: Path | str, layout: RobotsLayout | None,
                 events: tuple[EventSpec, ...]):
        self.world, self.events = world, tuple(events)
        self.spec = world_spec(world, layout)
        self.model = compile_world(self.spec, world)
        self.applied = 0

    def advance(self, data: mujoco.MjData, time_ns: int
                ) -> tuple[mujoco.MjModel, mujoco.MjData] | None:
        """Apply the events due by ``time_ns`` that are not applied yet: the new model and
        data (every other body's state kept; kinematics and sensors computed), or None
        when none is due."""
        due = applied_by(self.events, time_ns)
        if due == self.applied:
            return None
        for event in self.events[self.applied:due]:
            apply_event(self.spec, event)
        try:
            model, data = self.spec.recompile(self.model, data)
        except (ValueError, mujoco.FatalError) as exc:
            names = ", ".join(e.name for e in self.events[self.applied:due])
            raise ValueError(f"the world with {names} does not compile: {exc}") from exc
        mujoco.mj_forward(model, data)
        self.model, self.applied = model, due
        return model, data

    @property
    def version(self) -> int:
        """How many events are in the world now."""
        return self.applied


@functools.lru_cache(maxsize=8)
def model_at(world: str, layout: RobotsLayout | None, events: tuple[EventSpec, ...],
             version: int) -> mujoco.MjModel:
    """The world with the first ``version`` events applied, compiled (cached per process:
    the nodes of a process that mirror one world share its models; they only read them)."""
    if version == 0:
        return load_model(world, layout)
    spec = world_spec(world, layout)
    for event in events[:version]:
        apply_event(spec, event)
    return compile_world(spec, world)


def geom_map(old: mujoco.MjModel, new: mujoco.MjModel) -> np.ndarray:
    """For each geom of ``old``, its id in ``new`` (-1: gone), matched by body name and
    place among the body's geoms."""
    def keys(model: mujoco.MjModel) -> list[tuple[str, int]]:
        seen: dict[int, int] = {}
        out = []
        for g in range(model.ngeom):
            body = int(model.geom_bodyid[g])
            seen[body] = seen.get(body, -1) + 1
            out.append((model.body(body).name, seen[body]))
        return out

    index = {key: g for g, key in enumerate(keys(new))}
    return np.array([index.get(key, -1) for key in keys(old)], dtype=np.int64)
