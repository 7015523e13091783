"""effort_controllers/JointGroupEffortController: a forward command controller whose joints
take effort commands (``~/commands``, one value per joint)."""

from __future__ import annotations

from nodes.ros2_control.controllers.forward_command_controller import JointGroupController


class JointGroupEffortController(JointGroupController):
    """``~/commands`` to its joints' effort command interfaces."""

    fixed_interface = "effort"
