"""ros2_control's standard controllers, stepped in lockstep: the user's own controllers file
(``controller_manager: ros__parameters:``) read once (``config``), each controller type one
module under ``controllers/`` behind one interface (``interface``, shaped like
ControllerInterfaceBase) found by its type name (``registry``), the manager's logic without
transport (``manager``), the hardware it reads and writes (``hardware``), and the controller
manager as one step node between physics and the ROS 2 world (``node``)."""
