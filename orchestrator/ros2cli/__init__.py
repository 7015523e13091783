"""cosim-ros2: the everyday verbs of ros2cli (topic, service, action, param, and
ros2controlcli's control) for a pip-only install, where the ROS 2 wheels carry rclpy but no
``ros2`` command. The arguments follow ros2cli's: message values in YAML
(``"{linear: {x: 0.5}}"``), types as ``pkg/msg/Name`` or ``pkg/Name``. One module per verb
group; :mod:`orchestrator.ros2cli.cli` puts them together."""
