"""A mirror of a zenoh run onto ROS 2 (DDS), for ordinary ros2 tools (the scenario's
``zenoh.mirror_to_dds``). It lives in the orchestrator, beside the zenoh transport rather
than inside it: the transport carries the run, the mirror only watches it."""

from __future__ import annotations

import zenoh


class DdsMirror:
    """Republishes chosen zenoh topics on ROS 2 (DDS), so ordinary ros2 tools can watch a run.

    Runs in the orchestrator's process: one rclpy node, one publisher per mirrored topic
    (made at once when the run's plan knows the topic's type, so ROS tools discover it
    while the nodes start; else on the first sample, with the type the key expression
    names), fed by zenoh subscribers whose callbacks run on a Python thread of their own.
    Best effort: it never holds the lockstep up, and what it shows is not part of the run
    digest. A ``latched`` topic (/tf_static) is republished latched (transient-local).
    """

    def __init__(self, session: zenoh.Session, domain: int, topics: list[str],
                 types: dict[str, type] | None = None, latched: frozenset[str] = frozenset()):
        import rclpy

        from runtime.transport.ros2 import (
            no_signal_handlers,
            reliable_qos,
            use_cosim_dds_profile,
        )

        use_cosim_dds_profile()
        self._qos = reliable_qos(100)
        self._latched_qos = reliable_qos(1, latched=True)
        self._latched = latched
        self._context = rclpy.Context()
        rclpy.init(context=self._context, signal_handler_options=no_signal_handlers())
        self.node = rclpy.create_node("cosim_zenoh_mirror", context=self._context,
                                      start_parameter_services=False, enable_rosout=False)
        self._publishers: dict[str, object] = {
            topic: self.node.create_publisher(types[topic], topic, self._qos_of(topic))
            for topic in topics if types and topic in types}
        self._subs = [session.declare_subscriber(
            f"{domain}/{topic.strip('/')}/*/*",
            zenoh.handlers.Callback(lambda sample, t=topic: self._forward(t, sample)))
            for topic in topics]

    def _forward(self, topic: str, sample: zenoh.Sample) -> None:
        pub = self._publishers.get(topic)
        if pub is None:
            name = str(sample.key_expr).split("/")[-2]  # 'pkg::msg::dds_::Type_'
            package, kind, _, type_ = name.split("::")
            module = __import__(f"{package}.{kind}", fromlist=[type_[:-1]])
            pub = self.node.create_publisher(getattr(module, type_[:-1]), topic,
                                             self._qos_of(topic))
            self._publishers[topic] = pub
        pub.handle.publish_raw(sample.payload.to_bytes())

    def _qos_of(self, topic: str):
        return self._latched_qos if topic in self._latched else self._qos

    def close(self) -> None:
        """Stop forwarding and shut the rclpy context down."""
        import rclpy

        for sub in self._subs:
            sub.undeclare()
        self.node.destroy_node()
        if self._context.ok():
            rclpy.shutdown(context=self._context)
