"""What a node needs of the robot model, worded for the format the robot is described in: a
URDF user adds a sensor with ``robots.urdf.sensors`` or a Gazebo ``<sensor>`` tag (cosim's
MuJoCo names are no concern of theirs); an MJCF or USD user names the site or camera the
sensor reads, as cosim's conventions or the node's parameters say."""

from __future__ import annotations

from pathlib import Path

import mujoco

from descriptions.robot_model import RobotModel, SensorKind

GAZEBO_TYPES = {"lidar": "ray", "camera": "camera", "imu": "imu"}
MJCF_OBJECTS = {"lidar": "site", "camera": "camera", "imu": "site"}
_OBJECT_TYPES = {"site": mujoco.mjtObj.mjOBJ_SITE, "camera": mujoco.mjtObj.mjOBJ_CAMERA}


def missing_sensor(robot: RobotModel, kind: SensorKind, key: str, mjcf_name: str,
                   name_key: str, world: mujoco.MjModel | None = None
                   ) -> list[tuple[str, str, str]]:
    """[(key, problem, accepted)] when ``robot`` has no ``kind`` sensor (nor, given the
    ``world``, does the world have the object ``mjcf_name`` that a node without it falls
    back to), else []: for a URDF robot, the scenario entry or Gazebo tag that adds one; for
    another, the MJCF object (``mjcf_name``, unscoped) the sensor is read by and the node
    parameter (``name_key``) that names another."""
    what = MJCF_OBJECTS[kind]
    if robot.sensor(kind) is not None or (
            world is not None and mujoco.mj_name2id(world, _OBJECT_TYPES[what], mjcf_name) >= 0):
        return []
    source = Path(robot.source).name or "the world"
    if robot.reader == "usd":
        return [(key, f"the robot has no {kind}: {source} hangs none on a link or frame.",
                 f"add robots.usd.sensors: {{{kind}: PRIM}} (the name of the link or frame "
                 f"prim it hangs on)" + (", or a UsdGeom.Camera prim under a link."
                                         if kind == "camera" else "."))]
    if robot.reader == "urdf":
        gazebo = GAZEBO_TYPES[kind]
        return [(key, f"the robot has no {kind}: {source} hangs none on a link (no Gazebo "
                 f"{gazebo} sensor tag, no robots.urdf.sensors entry).",
                 f"add robots.urdf.sensors: {{{kind}: LINK}} (the link it hangs on) or a "
                 f"Gazebo {gazebo} sensor tag on that link (<gazebo reference=\"LINK\"><sensor "
                 f"type=\"{gazebo}\">).")]
    return [(key, f"the robot has no {kind}: {source} has no {what} {mjcf_name!r} on it.",
             f"a {what} named {mjcf_name!r} on the robot where its {kind} is, or {name_key} "
             f"naming the robot's {kind} {what}.")]
