"""The robot's topic names, in one place, relative to the robot: a namespace prefix
(``/robot_3``) applies to each of them through ``in_namespace``."""

from __future__ import annotations

CMD_VEL = "/cmd_vel"
ODOM = "/odom"
JOINT_COMMANDS = "/joint_commands"
JOINT_STATES = "/joint_states"


def in_namespace(namespace: str, topic: str) -> str:
    """``topic`` under ``namespace`` ('' or '/' for the root): ('/robot_3', '/odom') ->
    '/robot_3/odom'."""
    namespace = namespace.strip("/")
    return f"/{namespace}{topic}" if namespace else topic
