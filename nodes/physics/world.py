"""Loading a world (MJCF or USD) and reading the robot out of it (physics, sensors, control)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from descriptions.swarm_world import swarm_model
from descriptions.worldfile import load_world_model
from plan.timeutil import NS_PER_S


def load_model(world: Path | str, robots=None) -> mujoco.MjModel:
    """Compile the world file, MJCF or USD, through the one shared loader (descriptions.worldfile);
    with a swarm's ``robots`` (plan.robots.RobotsLayout), the arena with every robot."""
    if robots is not None:
        return swarm_model(Path(world), robots)
    return load_world_model(world)


def timestep_ns(model: mujoco.MjModel, world: Path | str) -> int:
    """The world's timestep as an exact number of nanoseconds, or a ValueError saying why not."""
    ns = round(model.opt.timestep * NS_PER_S)
    if ns <= 0 or abs(ns / NS_PER_S - model.opt.timestep) > 1e-12:
        raise ValueError(f"world {world}: timestep {model.opt.timestep!r} s is not a whole "
                         "number of nanoseconds; use e.g. 0.002 or 0.001")
    return ns


def substeps(model: mujoco.MjModel, world: Path | str, period_ns: int) -> int:
    """How many world timesteps make one node period; a ValueError unless a whole number."""
    step = timestep_ns(model, world)
    if period_ns % step:
        raise ValueError(f"world {world}: timestep {step} ns does not divide the physics node "
                         f"period {period_ns} ns; choose a rate whose period is a multiple of "
                         f"{step} ns or change <option timestep> in the world")
    return period_ns // step


def body_id(model: mujoco.MjModel, name: str) -> int:
    """The id of a named body, or a ValueError listing what exists."""
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if i < 0:
        names = [model.body(j).name for j in range(model.nbody)]
        raise ValueError(f"the world has no body {name!r}; bodies: {names}")
    return i


def named_id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    """The id of a named joint, site, camera, ...; a ValueError when absent."""
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise ValueError(f"the world has no {kind.name[6:].lower()} named {name!r}")
    return i


def robot_geoms(model: mujoco.MjModel, base: str) -> np.ndarray:
    """Boolean mask over geoms: those on the robot (any body under ``base``)."""
    root = model.body_rootid[body_id(model, base)]
    return model.body_rootid[model.geom_bodyid] == root


def wheel_geometry(model: mujoco.MjModel, left_joint: str, right_joint: str) -> tuple[float, float]:
    """(wheel radius, wheel separation) read from the wheel joints' bodies and their geoms."""
    radii, ys = [], []
    for name in (left_joint, right_joint):
        j = named_id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        body = model.jnt_bodyid[j]
        geoms = np.flatnonzero(model.geom_bodyid == body)
        if geoms.size == 0:
            raise ValueError(f"wheel joint {name!r} moves a body without a geom")
        radii.append(float(model.geom_size[geoms[0], 0]))
        ys.append(float(model.body_pos[body, 1]))
    return 0.5 * (radii[0] + radii[1]), abs(ys[0] - ys[1])
