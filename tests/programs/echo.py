"""A plain rclpy program for foreign-node tests: on every Int64 on 'in', publish 'copies'
Int64 messages on 'out' (value + 1). copies=2 publishes too many, copies=0 too few."""

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from std_msgs.msg import Int64


class Echo(Node):
    """Answers each input with a configurable number of outputs."""

    def __init__(self):
        super().__init__("echo")
        self.copies = self.declare_parameter("copies", 1).value
        self.pub = self.create_publisher(Int64, "out", 10)
        self.create_subscription(Int64, "in", self.on_in, 10)

    def on_in(self, msg: Int64) -> None:
        """Publish the configured number of answers."""
        for _ in range(self.copies):
            self.pub.publish(Int64(data=msg.data + 1))


def main() -> None:
    """Spin until shut down."""
    rclpy.init()
    node = Echo()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
