"""Loading a world (MJCF or USD) and the robots a node serves (physics, sensors, control)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import mujoco

from descriptions.robot_model import RobotModel
from descriptions.robot_reader import RobotNames, world_robots
from descriptions.swarm_world import swarm_model
from descriptions.worldfile import load_world_model
from nodes.contract import NodeConfig
from plan.robots import RobotsLayout, robot_of
from plan.timeutil import NS_PER_S, Ns, format_ns


def load_model(world: Path | str, layout: RobotsLayout | None = None) -> mujoco.MjModel:
    """Compile the world file, MJCF or USD, through the one shared loader
    (descriptions.worldfile); with a swarm's ``layout``, the arena with every robot."""
    if layout is not None:
        return swarm_model(Path(world), layout)
    return load_world_model(world)


def robots_of(config: NodeConfig, names: dict[str, Any]) -> tuple[RobotModel, ...]:
    """The robots a node serves: its config's, read once by the description loader for the
    scenario; for a node made outside a scenario (a test, a benchmark) with none given, the
    world's robots read by cosim's conventions and the node's own ``names`` (a robot's node,
    NAME@ROBOT: its own)."""
    if config.robots:
        return config.robots
    if config.world is None:
        return ()
    robots = world_robots(Path(config.world), config.layout, RobotNames.of(names))
    own = robot_of(config.name)
    return robots if own is None else tuple(r for r in robots if r.name == own)


def swarm_of(config: NodeConfig, names: dict[str, Any]) -> tuple[RobotModel, ...]:
    """Every robot of a swarm's world, as ``robots_of`` gives a node its own: its config's
    (``NodeConfig.swarm``) or, for a node made outside a scenario, the world's read by
    cosim's conventions and the node's ``names``; () without a swarm."""
    if config.swarm or config.layout is None or config.world is None:
        return config.swarm
    return world_robots(Path(config.world), config.layout, RobotNames.of(names))


def timestep_ns(model: mujoco.MjModel, world: Path | str) -> int:
    """The world's timestep as an exact number of nanoseconds, or a ValueError saying why not."""
    ns = round(model.opt.timestep * NS_PER_S)
    if ns <= 0 or abs(ns / NS_PER_S - model.opt.timestep) > 1e-12:
        raise ValueError(f"world {world}: timestep {model.opt.timestep!r} s is not a whole "
                         "number of nanoseconds; use e.g. 0.002 or 0.001")
    return ns


def substeps(model: mujoco.MjModel, world: Path | str, period_ns: Ns) -> int:
    """How many world timesteps make one node period; a ValueError unless a whole number."""
    step = timestep_ns(model, world)
    if period_ns % step:
        raise ValueError(f"world {world}: timestep {step} ns does not divide the physics node "
                         f"period {format_ns(period_ns)}; choose a rate whose period is a "
                         f"multiple of {step} ns or change <option timestep> in the world")
    return int(period_ns // step)


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


def start_joints(model: mujoco.MjModel, data: mujoco.MjData,
                 robots: tuple[RobotModel, ...]) -> None:
    """Each robot's joints where its ``<ros2_control>`` block starts them: the
    ``initial_value`` of a position state interface into qpos (and the target of the
    joint's position servo, which holds it there), of a velocity one into qvel, as
    mock_components and gz_ros2_control start their joints. Called at every reset (a
    ResetSimulation sets them again); a robot not in the world now is skipped."""
    for robot in robots:
        for joint in robot.control:
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint.joint)
            if j < 0 or not joint.initial:
                continue
            for interface, value in joint.initial:
                if interface == "position":
                    data.qpos[model.jnt_qposadr[j]] = value
                    for a in range(model.nu):
                        if (int(model.actuator_trnid[a, 0]) == j
                                and model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                                and model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
                                and model.actuator_biasprm[a, 1] != 0.0):
                            data.ctrl[a] = value
                elif interface == "velocity":
                    data.qvel[model.jnt_dofadr[j]] = value
