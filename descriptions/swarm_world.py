"""The swarm world: the arena with one prefixed copy of the robot description per robot
(plan/robots.py says what a swarm is), compiled the same way in every process."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco

from descriptions.readers import robot_spec
from descriptions.worldfile import compile_world, load_world_spec, quiet_empty_prefix
from plan.robots import RobotsLayout

GROUP = 32
"""Robots attached into one spec of their own before that is attached to the world: an
attach costs in proportion to the spec attached into (MuJoCo 4.0), so a thousand robots
attached one by one into the world cost a thousand times the growing world (8.8 s of the
start-up at 1,000 robots); in groups of 32, 0.9 s. The compiled model is the same byte for
byte: a group's frame is the identity, and its elements keep their order."""


def swarm_model(world: Path, layout: RobotsLayout) -> mujoco.MjModel:
    """The compiled swarm world (cached per process: nodes only read the model; a process
    the orchestrator execs is handed the orchestrator's, ``hand_over`` and ``take_over``)."""
    key = (Path(world), layout)
    model = _COMPILED.pop(key, None)
    if model is None:
        model = compile_world(swarm_spec(world, layout), world)
        if len(_COMPILED) >= 4:
            _COMPILED.pop(next(iter(_COMPILED)))  # the least recently asked for
    _COMPILED[key] = model
    return model


_COMPILED: dict[tuple[Path, RobotsLayout], mujoco.MjModel] = {}
"""swarm_model's models, the most recently asked for last."""


def hand_over(world: Path) -> list[tuple[Path, RobotsLayout, mujoco.MjModel]]:
    """The swarm models of ``world`` this process compiled, for a process it execs (a
    model pickles as its MJB, 14 MB and 0.02 s at 1,000 robots, where building and
    compiling it again took 2.6 CPU s in every exec'd process)."""
    return [(w, layout, model) for (w, layout), model in _COMPILED.items()
            if w == Path(world)]


def take_over(models: list[tuple[Path, RobotsLayout, mujoco.MjModel]]) -> None:
    """Keep the models ``hand_over`` gave (unpickled): ``swarm_model`` answers with them."""
    for world, layout, model in models:
        _COMPILED[(Path(world), layout)] = model


def swarm_spec(world: Path, layout: RobotsLayout) -> mujoco.MjSpec:
    """The arena with one prefixed copy of the description per robot in it at time 0, at
    its start (a robot that enters later is attached then: ``attach_robot``)."""
    spec = load_world_spec(world, stage_robots_too=False)  # a stage's robots: attached here
    spec.copy_during_attach = True
    robots = layout.at_start.robots
    for first in range(0, len(robots), GROUP):
        group = mujoco.MjSpec()
        for r in robots[first:first + GROUP]:  # a described robot: read once per process
            attach_robot(group, robot_spec(*layout.source_of(r.name)), r.name, r.start)
        with quiet_empty_prefix():  # the robots' names are prefixed already
            spec.attach(group, frame=spec.worldbody.add_frame(), prefix="")
    return spec


def attach_robot(spec: mujoco.MjSpec, robot: mujoco.MjSpec, name: str,
                 start: tuple[float, float, float]) -> None:
    """Attach a copy of ``robot`` to the world body of ``spec`` at ``start`` (x, y, yaw),
    every name prefixed ``NAME/``."""
    x, y, yaw = start
    spec.copy_during_attach = True
    frame = spec.worldbody.add_frame(pos=[x, y, 0.0],
                                     quat=[math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    spec.attach(robot, frame=frame, prefix=f"{name}/")
