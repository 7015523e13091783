#!/usr/bin/env python3
"""cosim's built-in navigation controller as a plain rclpy node: an ordinary ROS 2 program
(its own node, executor and callbacks) that computes exactly what the built-in control
node computes.

It subscribes to ``odom`` and ``scan`` and, in the scan callback, steps the controller with
the latest odometry and publishes ``cmd_vel`` and ``plan`` stamped with sim time. Run in
lockstep as a foreign program (``bench/foreign_nav.py``, ``tests/test_foreign_nav.py``),
whose declared inputs are ``/odom`` then ``/scan`` so the odometry of a tick is taken before
its scan, it gives the built-in controller's digest; against a live robot or simulator it
is just a navigation node. With ``timer_hz`` > 0 both callbacks only store, and a timer at
that rate on sim time steps the controller and publishes (the usual control-node shape;
it then publishes nothing at tick 0, so its digest differs from the built-in one there).

    python examples/control_as_ros_node.py --ros-args -p use_sim_time:=true \\
        -p scenario:=scenarios/nav.yaml [-p timer_hz:=10.0]
"""

import rclpy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry, Path
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from sensor_msgs.msg import LaserScan

import nodes  # noqa: F401 - provides the node kinds to the plan (plan.kinds)
from descriptions.load import load_scenario
from nodes.contract import Tick
from plan.timeutil import tick_at_ns
from runtime.build import make_node


class ControlAsRosNode(Node):
    """The built-in controller behind ordinary ROS 2 subscriptions and publishers."""

    def __init__(self):
        super().__init__("control")
        scenario = load_scenario(self.declare_parameter("scenario", "scenarios/nav.yaml").value)
        name = self.declare_parameter("node", "control").value
        self.controller = make_node(scenario, name)
        self.tick_ns = scenario.tick_ns
        timer_hz = float(self.declare_parameter("timer_hz", 0.0).value)
        self.odom: Odometry | None = None
        self.scan: LaserScan | None = None
        self.cmd_pub = self.create_publisher(Twist, "cmd_vel", 10)
        self.plan_pub = self.create_publisher(Path, "plan", 10)
        self.create_subscription(Odometry, "odom", self.on_odom, 10)
        self.create_subscription(LaserScan, "scan", self.on_scan, 10)
        self.timer_driven = timer_hz > 0
        if self.timer_driven:
            self.create_timer(1.0 / timer_hz, self.on_timer)

    def on_odom(self, msg: Odometry) -> None:
        """Keep the latest odometry."""
        self.odom = msg

    def on_scan(self, msg: LaserScan) -> None:
        """Keep the scan; without a timer, one control step per scan."""
        self.scan = msg
        if not self.timer_driven:
            self.step(msg)

    def on_timer(self) -> None:
        """One control step with the latest odometry and scan (none before both came)."""
        if self.odom is not None and self.scan is not None:
            self.step(self.scan)

    def step(self, msg: LaserScan) -> None:
        """Step the controller with the latest odometry and this scan, and publish."""
        now = self.get_clock().now()
        tick = Tick(tick_at_ns(now.nanoseconds, self.tick_ns), now.nanoseconds)
        out = self.controller.step(tick, {"/odom": self.odom, "/scan": msg})
        for text in self.controller.take_notes():  # why it stands still, when it does
            self.get_logger().warning(text)
        out["/plan"].header.stamp = now.to_msg()
        self.cmd_pub.publish(out["/cmd_vel"])
        self.plan_pub.publish(out["/plan"])


def main() -> None:
    """Spin until Ctrl-C or shutdown, without a traceback."""
    rclpy.init()
    node = ControlAsRosNode()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
