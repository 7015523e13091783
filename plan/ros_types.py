"""ROS 2 type names and the rclpy classes they name: 'geometry_msgs/msg/Twist' both ways."""

from __future__ import annotations

import importlib


def ros_type(cls: type) -> str:
    """'sensor_msgs/msg/LaserScan' for an rclpy message class ('pkg/srv/Name' for services,
    'pkg/action/Name' for actions)."""
    package, _, rest = cls.__module__.partition(".")
    kind = rest.partition(".")[0]
    if kind not in ("msg", "srv", "action"):  # the generated modules are pkg.msg._name
        kind = "srv" if hasattr(cls, "Request") and hasattr(cls, "Response") else "msg"
        if hasattr(cls, "Goal") and hasattr(cls, "Feedback"):
            kind = "action"
    return f"{package}/{kind}/{cls.__name__}"


def message_class(name: str) -> type:
    """'geometry_msgs/msg/Twist' (or 'geometry_msgs/Twist') -> the rclpy message class;
    ValueError naming the type when it is malformed or not installed."""
    parts = name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or not all(parts):
        raise ValueError(f"{name!r} is not a message type like 'geometry_msgs/msg/Twist'")
    try:
        module = importlib.import_module(f"{parts[0]}.{parts[1]}")
        if hasattr(module, parts[2]):
            return getattr(module, parts[2])
        # an action's parts ('FollowJointTrajectory_Goal') live on the action's class
        outer, _, inner = parts[2].rpartition("_")
        return getattr(getattr(module, outer), inner)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"message type {name!r} is not installed ({exc})") from None
