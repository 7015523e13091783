"""The controller types cosim runs, keyed by the type name a controllers file gives
(``<package>/<Class>``, as pluginlib names them upstream). Adding a type is one module under
``nodes/ros2_control/controllers/`` and one entry here; nothing else asks for a type."""

from __future__ import annotations

from nodes.ros2_control.controllers.diff_drive_controller import DiffDriveController
from nodes.ros2_control.controllers.effort_controllers import JointGroupEffortController
from nodes.ros2_control.controllers.forward_command_controller import ForwardCommandController
from nodes.ros2_control.controllers.joint_state_broadcaster import JointStateBroadcaster
from nodes.ros2_control.controllers.joint_trajectory_controller import (
    JointTrajectoryController,
)
from nodes.ros2_control.controllers.parallel_gripper_action_controller import (
    ParallelGripperActionController,
)
from nodes.ros2_control.controllers.position_controllers import JointGroupPositionController
from nodes.ros2_control.controllers.velocity_controllers import JointGroupVelocityController
from nodes.ros2_control.interface import ControllerInterface

CONTROLLER_TYPES: dict[str, type[ControllerInterface]] = {
    "joint_state_broadcaster/JointStateBroadcaster": JointStateBroadcaster,
    "joint_trajectory_controller/JointTrajectoryController": JointTrajectoryController,
    "forward_command_controller/ForwardCommandController": ForwardCommandController,
    "position_controllers/JointGroupPositionController": JointGroupPositionController,
    "velocity_controllers/JointGroupVelocityController": JointGroupVelocityController,
    "effort_controllers/JointGroupEffortController": JointGroupEffortController,
    "diff_drive_controller/DiffDriveController": DiffDriveController,
    "parallel_gripper_action_controller/GripperActionController":
        ParallelGripperActionController,
}
BASE_CLASS = "controller_interface::ControllerInterface"
"""What list_controller_types gives as every type's base class."""


def controller_class(type_name: str) -> type[ControllerInterface] | None:
    """The class of controller type ``type_name``, or None when cosim does not serve it."""
    return CONTROLLER_TYPES.get(type_name)


def served_types() -> list[str]:
    """Every type cosim runs, in the registry's order."""
    return list(CONTROLLER_TYPES)
