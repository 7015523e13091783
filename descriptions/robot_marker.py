"""The mark a described robot leaves in its MuJoCo fragment (one a reader of
``descriptions.readers`` made: URDF, xacro, USD): a MuJoCo custom text holding its root
link and IMU link, so a check that has only the compiled world (a node's
``world_problems``) can tell that robot's names are its model's, not cosim's conventions,
without knowing the format it came from. In a swarm the text is prefixed ``ROBOT/`` as every
name of the robot is."""

from __future__ import annotations

import json

import mujoco

MARKER = "cosim_urdf"  # the text's name, unchanged since URDF was the one described format


def mark(spec: mujoco.MjSpec, root: str, imu: str) -> None:
    """Mark the robot of ``spec``: its root link and its IMU link ('' without one)."""
    spec.add_text(name=MARKER, data=json.dumps({"root": root, "imu": imu}))


def described_robot_in(model: mujoco.MjModel, robot: str = "") -> dict[str, str] | None:
    """What a compiled world says of its robot ``robot`` (the unnamed one: '') when a
    description reader made it: its root link and IMU link ('' without one); None for a
    robot read from the world by its names (MJCF)."""
    name = f"{robot}/{MARKER}" if robot else MARKER
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, name)
    if i < 0:
        return None
    adr, size = int(model.text_adr[i]), int(model.text_size[i])
    return json.loads(bytes(model.text_data[adr:adr + size - 1]).decode())
