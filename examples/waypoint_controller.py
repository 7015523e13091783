#!/usr/bin/env python3
"""A plain rclpy waypoint follower: only rclpy and standard messages, no cosim import.

It publishes one geometry_msgs/Twist on ``cmd_vel`` for every nav_msgs/Odometry it
receives on ``odom``: steer towards the next waypoint, slow down while misaligned, and at
the last one turn to ``goal_yaw`` and stop. With ``timer_hz`` > 0 it has the shape most
control nodes have instead: the odometry callback only stores the latest message, and a
timer at that rate (on sim time, with ``use_sim_time``) computes and publishes the command,
so it publishes nothing until the timer first fires and nothing between firings. Being a
function of the odometry it receives, it runs deterministically in cosim's lockstep
(scenarios/nav_foreign.yaml), and just as well against any live robot or simulator.

    python examples/waypoint_controller.py --ros-args -p use_sim_time:=true \\
        -p waypoints:="[1.0, 0.0, 1.0, 1.0]" [-p timer_hz:=10.0]
"""

import math

import rclpy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node


def yaw_of(q) -> float:
    """Yaw of a geometry_msgs/Quaternion."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def wrap(angle: float) -> float:
    """An angle in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def clamp(value: float, limit: float) -> float:
    """value limited to [-limit, limit]."""
    return max(-limit, min(limit, value))


class WaypointController(Node):
    """Follows a list of (x, y) waypoints given as a flat 'waypoints' parameter."""

    def __init__(self):
        super().__init__("waypoint_controller")
        flat = self.declare_parameter("waypoints", [0.0, 0.0]).value
        self.waypoints = list(zip(flat[0::2], flat[1::2], strict=True))
        self.goal_yaw = self.declare_parameter("goal_yaw", 0.0).value
        self.max_speed = self.declare_parameter("max_speed", 0.5).value
        self.max_turn = self.declare_parameter("max_turn", 1.5).value
        self.reach = self.declare_parameter("reach_distance", 0.2).value
        timer_hz = float(self.declare_parameter("timer_hz", 0.0).value)
        self.index = 0
        self.latest: Odometry | None = None
        self.cmd_pub = self.create_publisher(Twist, "cmd_vel", 10)
        self.create_subscription(Odometry, "odom", self.on_odom, 10)
        self.timer_driven = timer_hz > 0
        if self.timer_driven:
            self.create_timer(1.0 / timer_hz, self.on_timer)

    def on_odom(self, odom: Odometry) -> None:
        """Store the odometry; without a timer, answer it with a command at once."""
        self.latest = odom
        if not self.timer_driven:
            self.command(odom)

    def on_timer(self) -> None:
        """Publish the command for the latest odometry (none before the first)."""
        if self.latest is not None:
            self.command(self.latest)

    def command(self, odom: Odometry) -> None:
        """Steer towards the current waypoint and publish one command."""
        pose = odom.pose.pose
        x, y, yaw = pose.position.x, pose.position.y, yaw_of(pose.orientation)
        while self.index < len(self.waypoints) - 1 and self._distance(x, y) < self.reach:
            self.index += 1
        cmd = Twist()
        tx, ty = self.waypoints[self.index]
        last = self.index == len(self.waypoints) - 1
        if last and self._distance(x, y) < 0.1:
            error = wrap(self.goal_yaw - yaw)
            cmd.angular.z = clamp(2.0 * error, self.max_turn) if abs(error) > 0.05 else 0.0
        else:
            error = wrap(math.atan2(ty - y, tx - x) - yaw)
            cmd.angular.z = clamp(2.5 * error, self.max_turn)
            speed = self.max_speed * max(0.0, math.cos(error)) ** 2
            cmd.linear.x = min(speed, 0.8 * self._distance(x, y)) if last else speed
        self.cmd_pub.publish(cmd)

    def _distance(self, x: float, y: float) -> float:
        tx, ty = self.waypoints[self.index]
        return math.hypot(tx - x, ty - y)


def main() -> None:
    """Spin until Ctrl-C or shutdown, without a traceback."""
    rclpy.init()
    node = WaypointController()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
