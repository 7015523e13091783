"""ros2_controllers' standard controllers, one module per type, each behind
``nodes.ros2_control.interface.ControllerInterface``; ``nodes.ros2_control.registry`` maps
their type names to them."""
