"""The ROS 2 surface users expect of a simulator: run control (pause, step, reset),
simulation_interfaces services, entity state, NavigateToPose and the parameter server."""
