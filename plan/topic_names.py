"""The robot's topic names, in one place and relative to the robot, so that a namespace
prefix (``/robot_3``) can be applied to them here rather than at every use."""

from __future__ import annotations

CMD_VEL = "/cmd_vel"
ODOM = "/odom"
JOINT_COMMANDS = "/joint_commands"
JOINT_STATES = "/joint_states"
