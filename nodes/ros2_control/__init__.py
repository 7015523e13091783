"""ros2_control's standard controllers, stepped in lockstep: the user's own controllers file
(``controller_manager: ros__parameters:``) read once (``config``), each controller a pure
object updated at the manager's ``update_rate`` (``controllers``, ``trajectory``), and the
controller manager as one step node between physics and the ROS 2 world (``node``)."""
