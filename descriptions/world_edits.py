"""Objects put into and taken out of a world's MjSpec (a scenario's ``events:``,
``plan.events``), and what the load-time checks of those events read out of a world.

A spawned object is a body of its own appended to the world body (so every body, geom,
joint and qpos address of the world file and its robots stays where it was; only spawned
objects after a deleted one move up), named after the object: body, geom and, for a free
object, its free joint. Its geom is in group 0, which lidars and cameras see and the
robots' own geoms (group 3) are not in.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np

from descriptions.mesh_convert import mujoco_meshes
from descriptions.readers import robot_spec
from descriptions.swarm_world import attach_robot, swarm_spec
from descriptions.world_geometry import robot_footprint_radius, static_obstacles
from descriptions.worldfile import load_world_spec
from plan.events import EventSpec, ObjectSpec, WorldObjects
from plan.obstacles import Obstacle
from plan.robots import RobotsLayout

MESH_PREFIX = "cosim_object_"  # a spawned mesh's asset name: MESH_PREFIX + object name
SHAPE = {"box": mujoco.mjtGeom.mjGEOM_BOX, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
         "sphere": mujoco.mjtGeom.mjGEOM_SPHERE, "mesh": mujoco.mjtGeom.mjGEOM_MESH}


def world_spec(world: Path | str, layout: RobotsLayout | None = None) -> mujoco.MjSpec:
    """The world as an MjSpec, compiling to the model ``nodes.physics.world.load_model``
    gives: the file (MJCF or USD), or a swarm's arena with its robots."""
    if layout is not None:
        return swarm_spec(Path(world), layout)
    return load_world_spec(world)


def apply_event(spec: mujoco.MjSpec, event: EventSpec, layout: RobotsLayout | None = None
                ) -> None:
    """Spawn or delete ``event``'s object, or bring its robot in or take it out (a copy of
    ``layout``'s description, ``descriptions.swarm_world.attach_robot``), in ``spec`` (not
    compiled)."""
    if event.spawn is not None:
        add_object(spec, event.spawn)
    elif event.robot is not None:
        if layout is not None and layout.robots:  # an arena without robots takes none
            r = event.robot
            attach_robot(spec, robot_spec(*layout.source_of(r.name)), r.name,
                         (r.start.x, r.start.y, r.start.yaw))
    elif (root := robot_root(spec, event.delete, layout)) is not None:
        spec.delete(root)  # its joints, actuators and sensors go with it (MuJoCo >= 3.3)
    elif layout is None or layout.robots or spec.body(event.delete) is not None:
        remove_object(spec, event.delete)


def robot_root(spec: mujoco.MjSpec, name: str, layout: RobotsLayout | None):
    """The root body of robot ``name``'s copy in ``spec``, or None: no such robot."""
    if layout is None or name not in layout.names:
        return None
    return spec.body(f"{name}/{layout.base_of(name)}")


def add_object(spec: mujoco.MjSpec, obj: ObjectSpec) -> None:
    """Append ``obj`` to the world body: welded to the world (static) or on a free joint."""
    z = obj.pose.z if obj.pose.z is not None else (obj.half_height or 0.0)
    half = obj.pose.yaw / 2
    body = spec.worldbody.add_body(name=obj.name, pos=[obj.pose.x, obj.pose.y, z],
                                   quat=[math.cos(half), 0.0, 0.0, math.sin(half)])
    if not obj.static:
        body.add_freejoint(name=obj.name)
    geom = dict(name=obj.name, type=SHAPE[obj.shape], rgba=list(obj.rgba), group=0)
    if obj.shape == "box":
        geom["size"] = [s / 2 for s in obj.size]
    elif obj.shape == "cylinder":
        geom["size"] = [obj.size[0], obj.size[1] / 2, 0.0]
    elif obj.shape == "sphere":
        geom["size"] = [obj.size[0], 0.0, 0.0]
    else:
        parts = mujoco_meshes(Path(obj.mesh), whole=True)  # ASCII STL, COLLADA: converted
        spec.add_mesh(name=MESH_PREFIX + obj.name, file=parts[0].path if parts else obj.mesh,
                      scale=list(obj.scale))
        geom["meshname"] = MESH_PREFIX + obj.name
    if obj.mass is not None:
        geom["mass"] = obj.mass
    body.add_geom(**geom)


def object_problem(obj: ObjectSpec) -> str | None:
    """Why MuJoCo cannot make ``obj`` (a mesh file it cannot read, a degenerate mesh), or
    None: the object compiled on its own, before it goes into a world."""
    spec = mujoco.MjSpec()
    try:
        add_object(spec, obj)
        spec.compile()
    except (ValueError, mujoco.FatalError) as exc:
        return " ".join(str(exc).split())
    return None


def remove_object(spec: mujoco.MjSpec, name: str) -> None:
    """Take the spawned object ``name`` (its body, and its mesh asset) out of ``spec``."""
    body = spec.body(name)
    if body is None:
        raise ValueError(f"the world has no spawned object {name!r}")
    spec.delete(body)
    mesh = spec.mesh(MESH_PREFIX + name)
    if mesh is not None:
        spec.delete(mesh)


def world_objects(model: mujoco.MjModel, start: tuple[str, float, float] | None = None
                  ) -> WorldObjects:
    """What a scenario's events are checked against: the names of the world's bodies and
    geoms, its static obstacles, and each body on a free joint (a robot, a loose object)
    as a disc of its footprint where it starts (``start``: body name moved to (x, y))."""
    names = {model.body(b).name for b in range(model.nbody)}
    names |= {model.geom(g).name for g in range(model.ngeom)}
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    movers = []
    for j in np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE).tolist():
        body = int(model.jnt_bodyid[j])
        name = model.body(body).name
        x, y = (float(v) for v in data.xpos[body, :2])
        if start is not None and start[0] == name:
            x, y = start[1], start[2]
        radius = robot_footprint_radius(model, name) if name else 0.0
        movers.append(Obstacle(name=name or f"body {body}", geom=-1, kind="free body",
                               centre=(x, y), z_range=(-math.inf, math.inf), radius=radius))
    return WorldObjects(names=frozenset(n for n in names if n),
                        obstacles=tuple(static_obstacles(model)), movers=tuple(movers))
