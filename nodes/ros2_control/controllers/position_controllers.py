"""position_controllers/JointGroupPositionController: a forward command controller whose joints
take position commands (``~/commands``, one value per joint)."""

from __future__ import annotations

from nodes.ros2_control.controllers.forward_command_controller import JointGroupController


class JointGroupPositionController(JointGroupController):
    """``~/commands`` to its joints' position command interfaces."""

    fixed_interface = "position"
