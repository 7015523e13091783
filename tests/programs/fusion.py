"""A plain rclpy program with several inputs, as a user would write it (no cosim import):
it keeps the latest Int64 of each input and publishes their combination on 'out'.

Parameters: inputs (2 or 3: 'a', 'b' and maybe 'c'), order ('abc' or 'cba': the order the
subscriptions are created in), trigger ('b': publish in b's callback; 'timer': publish from
a 10 Hz sim-time timer), executor ('single' or 'multi'), copies (how many messages each
publication is: value, value + 1, ...), when ('always', or 'even': only when the sum of
the samples is even, a conditional publisher), qos ('default', or 'sensor': best-effort
subscriptions, sensor-data QoS), wall_clock (true: the node sets use_sim_time to false),
slow (the inputs whose callbacks work for work_ms milliseconds before they keep their
sample; '' for none) and reentrant (true: the callbacks share a reentrant callback group,
so a multi-threaded executor may run them at the same time; only the cosim gate keeps one
tick's callbacks one after another).

The value published is a function of the latest sample of every input:
a * 10^6 + b * 10^3 + c, or -1 while an input has not arrived yet."""

import time

import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data
from std_msgs.msg import Int64


class Fusion(Node):
    """Latest-value fusion of two or three inputs."""

    def __init__(self):
        super().__init__("fusion")
        if self.declare_parameter("wall_clock", False).value:
            self.set_parameters([Parameter("use_sim_time", value=False)])
        n = self.declare_parameter("inputs", 2).value
        order = self.declare_parameter("order", "abc").value
        trigger = self.declare_parameter("trigger", "b").value
        self.copies = self.declare_parameter("copies", 1).value
        self.when = self.declare_parameter("when", "always").value
        sensor = self.declare_parameter("qos", "default").value == "sensor"
        self.slow = self.declare_parameter("slow", "").value
        self.work_s = self.declare_parameter("work_ms", 0).value / 1000
        group = ReentrantCallbackGroup() if self.declare_parameter(
            "reentrant", False).value else None
        self.latest = {name: None for name in "abc"[:n]}
        self.pub = self.create_publisher(Int64, "out", 10)
        qos = qos_profile_sensor_data if sensor else 10
        for name in order:
            if name in self.latest:
                self.create_subscription(Int64, name, lambda m, k=name: self.on_input(k, m), qos,
                                         callback_group=group)
        self.trigger = trigger
        if trigger == "timer":
            self.create_timer(0.1, self.publish)

    def on_input(self, name: str, msg: Int64) -> None:
        """Keep the latest sample (after some work, if slow); 'b' may trigger the output."""
        if name in self.slow:
            time.sleep(self.work_s)  # what a callback that computes something takes
        self.latest[name] = msg.data
        if self.trigger == name:
            self.publish()

    def publish(self) -> None:
        """Publish the combination of the latest samples."""
        if any(v is None for v in self.latest.values()):
            value = -1
        else:
            value = sum(v * 1000 ** (2 - i) for i, v in enumerate(self.latest.values()))
        if self.when == "even" and (value < 0 or sum(self.latest.values()) % 2):
            return
        for i in range(self.copies):
            self.pub.publish(Int64(data=value + i))


def main() -> None:
    """Spin with the chosen executor until shut down."""
    rclpy.init()
    node = Fusion()
    multi = node.declare_parameter("executor", "single").value == "multi"
    try:
        if multi:
            executor = MultiThreadedExecutor(num_threads=4)
            executor.add_node(node)
            executor.spin()
        else:
            rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
