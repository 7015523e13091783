"""A world that changes while the run goes: the scenario's events (``plan.events``) applied
at their ticks, and clients' edits (SpawnEntity, DeleteEntity) at the tick they enter, the
same in every node that holds a copy of the world.

The physics node keeps the world's MjSpec and recompiles it at each change (``LiveWorld``:
MjSpec.recompile keeps the state of every body already there, bit for bit); a mirror (the
sensors') asks for the model of what physics publishes with every world state: how many
changes are in the world and, when they are not the scenario's first events, which
(``nodes.physics.messages.world_version``, ``model_at``), so a node that reaches the tick
first, or trails, poses the world that its input shows.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import mujoco
import numpy as np

from descriptions.world_edits import apply_event, object_problem, world_spec
from descriptions.worldfile import compile_world
from nodes.physics.world import load_model
from plan.events import EventSpec, edit_event
from plan.robots import BY_CLIENT, RobotsLayout


class LiveWorld:
    """The physics node's world: its spec, the model compiled from it, and what is in it:
    ``sequence``, the scenario's events (by index) and clients' edits (``EventSpec``s from
    /cosim/world_edits) in the order they were applied."""

    def __init__(self, world: Path | str, layout: RobotsLayout | None,
                 events: tuple[EventSpec, ...], note=None):
        self.world, self.events, self.layout = world, tuple(events), layout
        self.note = note or (lambda text: None)
        # the robots in the world now, by name (those of the start; events bring others in)
        self.robots = set() if layout is None else set(layout.at_start.names)
        self.spec = world_spec(world, layout)
        self.model = compile_world(self.spec, world)
        self.sequence: list[int | EventSpec] = []
        self.next_event = 0  # the first scenario event not yet due
        self.requested = 0  # clients' edits handled so far (applied or refused)
        self.spawned: set[str] = set()

    def take_over(self, model: mujoco.MjModel, data: mujoco.MjData) -> mujoco.MjData:
        """Data for this world's model holding the state of ``data`` of ``model``, the same
        world loaded otherwise (a world that had no events until a client asked for one)."""
        if (model.nq, model.nv, model.na, model.nu) != (self.model.nq, self.model.nv,
                                                        self.model.na, self.model.nu):
            raise ValueError(f"world {self.world}: its spec does not compile to the model "
                             "the run started with")
        mine = mujoco.MjData(self.model)
        for key in ("qpos", "qvel", "act", "ctrl", "qacc_warmstart", "mocap_pos",
                    "mocap_quat", "plugin_state"):
            getattr(mine, key)[:] = getattr(data, key)
        mine.time = data.time
        mujoco.mj_forward(self.model, mine)
        return mine

    def advance(self, data: mujoco.MjData, time_ns: int, edits: list[EventSpec] = ()
                ) -> tuple[mujoco.MjModel, mujoco.MjData] | None:
        """Apply the scenario's events due by ``time_ns`` and the clients' ``edits`` (every
        one asked for so far) not applied yet: the new model and data (every other body's
        state kept; kinematics and sensors computed), or None when nothing changed. An edit
        the world cannot take now (a name taken, a delete of what is not there) changes
        nothing and is noted."""
        applied = []
        while (self.next_event < len(self.events)
               and self.events[self.next_event].at <= time_ns):
            if self._apply(self.events[self.next_event], f"events[{self.next_event}]"):
                applied.append(self.next_event)
            self.next_event += 1
        for n in range(self.requested, len(edits)):
            if self._apply(edits[n], f"client edit {n + 1}"):
                applied.append(edits[n])
        self.requested = max(self.requested, len(edits))
        if not applied:
            return None
        try:
            model, data = self.spec.recompile(self.model, data)
        except (ValueError, mujoco.FatalError) as exc:
            names = ", ".join(self._name(a) for a in applied)
            raise ValueError(f"the world with {names} does not compile: {exc}") from exc
        mujoco.mj_forward(model, data)
        self.model = model
        self.sequence += applied
        return model, data

    def _name(self, item: int | EventSpec) -> str:
        return self.events[item].name if isinstance(item, int) else item.name

    def _apply(self, event: EventSpec, what: str) -> bool:
        name = event.name
        if event.robot is not None:
            if self.layout is None:
                self.note(f"{what}: robot {name!r} changes nothing: the scenario has no "
                          "robots: section to read its description from")
                return False
            if name in self.robots or name in self.spawned or name == "world":
                self.note(f"{what}: robot {name!r} changes nothing: the world has that name")
                return False
            apply_event(self.spec, event, self.layout)
            self.robots.add(name)
            return True
        if event.delete is not None and name in self.robots:
            if name not in {e.robot.name for e in self.events if e.robot is not None} | {
                    r.name for r in self.layout.robots if r.enter_ns == BY_CLIENT}:
                self.note(f"{what}: delete {name!r} changes nothing: only a robot an event "
                          "brought in can be taken out")
                return False
            apply_event(self.spec, event, self.layout)
            self.robots.discard(name)
            return True
        if event.delete is not None and name not in self.spawned:
            self.note(f"{what}: delete {name!r} changes nothing: no spawned object has "
                      "that name now")
            return False
        if event.spawn is not None and (name in self.spawned or name == "world" or (
                self.spec.body(name) is not None or self.spec.geom(name) is not None)):
            self.note(f"{what}: spawn {name!r} changes nothing: the world has that name")
            return False
        if event.spawn is not None and (problem := object_problem(event.spawn)):
            self.note(f"{what}: spawn {name!r} changes nothing: {problem}")
            return False
        apply_event(self.spec, event)
        if event.spawn is not None:
            self.spawned.add(name)
        else:
            self.spawned.discard(name)
        return True

    @property
    def version(self) -> int:
        """How many events and edits are in the world now."""
        return len(self.sequence)

    @property
    def label(self) -> str:
        """What is in the world, for a mirror to build it: '' when it is the scenario's
        first ``version`` events, else the sequence as JSON (``sequence_text``)."""
        if all(isinstance(item, int) for item in self.sequence) and \
                self.sequence == list(range(len(self.sequence))):
            return ""
        return sequence_text(self.sequence)


def sequence_text(sequence: list[int | EventSpec]) -> str:
    """A world's sequence as text: a scenario event's index, a client's edit as JSON."""
    items = [item if isinstance(item, int) else
             item.model_dump(exclude={"at"}, exclude_none=True, mode="json")
             for item in sequence]
    return json.dumps(items, sort_keys=True, separators=(",", ":"))


@functools.lru_cache(maxsize=8)
def model_at(world: str, layout: RobotsLayout | None, events: tuple[EventSpec, ...],
             version: int, label: str = "") -> mujoco.MjModel:
    """The world with what physics had applied when it published ``version`` and ``label``
    (``LiveWorld.label``: '' for the first ``version`` scenario events), compiled (cached
    per process: the nodes of a process that mirror one world share its models; they only
    read them)."""
    if version == 0:
        return load_model(world, layout)
    spec = world_spec(world, layout)
    sequence = json.loads(label) if label else list(range(version))
    for item in sequence:
        apply_event(spec, events[item] if isinstance(item, int) else edit_event(item), layout)
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
