"""velocity_controllers/JointGroupVelocityController: a forward command controller whose joints
take velocity commands (``~/commands``, one value per joint)."""

from __future__ import annotations

from nodes.ros2_control.controllers.forward_command_controller import JointGroupController


class JointGroupVelocityController(JointGroupController):
    """``~/commands`` to its joints' velocity command interfaces."""

    fixed_interface = "velocity"
