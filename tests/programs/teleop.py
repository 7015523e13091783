"""A teleop left running: a plain rclpy node publishing Twist on /cmd_vel at 20 Hz, on the
domain of ROS_DOMAIN_ID, until killed. Prints 'up' once its publisher exists and 'publishing'
once it has a subscriber."""

import sys
import time

import rclpy
from geometry_msgs.msg import Twist


def main() -> None:
    """Publish until killed."""
    rclpy.init()
    node = rclpy.create_node(sys.argv[1] if len(sys.argv) > 1 else "teleop_left_running")
    pub = node.create_publisher(Twist, "/cmd_vel", 10)
    print("up", flush=True)
    said = False
    while True:
        msg = Twist()
        msg.linear.x = 0.3
        pub.publish(msg)
        if not said and pub.get_subscription_count():
            print("publishing", flush=True)
            said = True
        time.sleep(0.05)


if __name__ == "__main__":
    main()
