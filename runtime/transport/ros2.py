"""The ros2 transport: rclpy over Fast DDS, with one persistent wait set and direct takes.

rclpy's executors cost several times the DDS latency per message, so the runtime does
not use them: it waits on an rcl wait set holding every subscription and takes raw CDR
bytes straight from the subscription handles (measured: about 8x faster than
``spin_once``). Every topic is still a real ROS 2 topic that ordinary tools see.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import rclpy
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from plan.robots import ros_name_chars
from runtime.transport.base import Publisher, Received, Subscription, Transport

PROFILE = Path(__file__).with_name("fastdds_profile.xml")


def use_cosim_dds_profile() -> None:
    """Use cosim's fast-discovery Fast DDS profile unless the user chose one."""
    if not (os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE")
            or os.environ.get("FASTDDS_DEFAULT_PROFILES_FILE")):
        os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(PROFILE)


def destroy_node(node) -> None:
    """Destroy an rclpy node and its action servers and clients: ``Node.destroy_node`` leaves
    those (waitables), and while one holds the node, the node's DDS participant stays in the
    graph, with servers that no longer answer."""
    for waitable in list(node.waitables):
        destroy = getattr(waitable, "destroy", None)
        if destroy is not None:
            destroy()
    node.destroy_node()


def reliable_qos(depth: int, latched: bool = False) -> QoSProfile:
    """Reliable, keep-last ``depth``: nothing is dropped while depth suffices. Volatile, or
    transient-local when ``latched`` (a late subscription still gets the last ``depth``)."""
    durability = DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE,
                      history=HistoryPolicy.KEEP_LAST, durability=durability)


class Ros2Publisher(Publisher):
    """An rclpy publisher fed with serialised bytes."""

    def __init__(self, topic: str, publisher):
        self.topic = topic
        self._pub = publisher
        self._raw = publisher.handle.publish_raw

    def publish(self, data: bytes) -> None:
        """Send CDR bytes without re-serialising."""
        self._raw(data)

    def matched(self) -> int:
        """Matched subscriptions."""
        return self._pub.get_subscription_count()

    def flush(self, timeout_s: float = 1.0) -> bool:
        """Wait until every matched subscription acknowledged what was sent."""
        return self._pub.wait_for_all_acked(rclpy.duration.Duration(seconds=timeout_s))


class Ros2Subscription(Subscription):
    """An rclpy subscription read by ``take_message`` in raw mode."""

    def __init__(self, topic: str, msg_type: type, subscription):
        self.topic = topic
        self.msg_type = msg_type
        self._sub = subscription
        self.handle = subscription.handle

    def matched(self) -> int:
        """Matched publishers."""
        return self._sub.get_publisher_count()


def ros_node_name(participant: str) -> str:
    """A valid ROS 2 node name for a participant: 'control@robot_3' -> 'control_robot_3';
    a long one (a packed process of many nodes) keeps its start and a hash of the whole."""
    name = ros_name_chars(participant)
    if len(name) > 120:
        name = f"{name[:100]}_{hashlib.sha256(participant.encode()).hexdigest()[:12]}"
    return name


class Ros2Transport(Transport):
    """One rclpy context and node per participant; the domain comes from ROS_DOMAIN_ID."""

    def __init__(self, participant: str):
        use_cosim_dds_profile()
        self._context = rclpy.Context()
        rclpy.init(context=self._context, signal_handler_options=no_signal_handlers())
        self.node = rclpy.create_node(ros_node_name(participant), context=self._context,
                                      start_parameter_services=False, enable_rosout=False)
        self._subs: list[Ros2Subscription] = []
        self._by_pointer: dict[int, Ros2Subscription] = {}
        self._waitset = None

    def publisher(self, topic: str, msg_type: type, depth: int,
                  latched: bool = False) -> Ros2Publisher:
        """A reliable rclpy publisher (transient-local when ``latched``)."""
        return Ros2Publisher(topic, self.node.create_publisher(msg_type, topic,
                                                               reliable_qos(depth, latched)))

    def subscription(self, topic: str, msg_type: type, depth: int,
                     latched: bool = False) -> Ros2Subscription:
        """A reliable rclpy subscription, never spun: the wait set reads it."""
        qos = reliable_qos(depth, latched)
        sub = self.node.create_subscription(msg_type, topic, _never_called, qos, raw=True)
        wrapped = Ros2Subscription(topic, msg_type, sub)
        self._subs.append(wrapped)
        self._by_pointer[sub.handle.pointer] = wrapped
        self._waitset = _rclpy.WaitSet(len(self._subs), 0, 0, 0, 0, 0, self._context.handle)
        return wrapped

    def wait(self, timeout_ns: int) -> list[Received]:
        """Wait on every subscription at once, then take all that is ready."""
        out: list[Received] = []
        for sub in self._subs:  # first drain what is already queued, without blocking
            _take_all(sub, out)
        if out or self._waitset is None:
            return out
        ws = self._waitset
        ws.clear_entities()
        for sub in self._subs:
            ws.add_subscription(sub.handle)
        ws.wait(timeout_ns)
        for pointer in ws.get_ready_entities("subscription"):
            _take_all(self._by_pointer[pointer], out)
        return out

    def publisher_nodes(self, topic: str) -> list[str]:
        """The full node names of ``topic``'s publishers, as the graph knows them."""
        return [f"{i.node_namespace.rstrip('/')}/{i.node_name}"
                for i in self.node.get_publishers_info_by_topic(topic)]

    def close(self) -> None:
        """Destroy the node and shut the context down."""
        try:
            destroy_node(self.node)
        finally:
            if self._context.ok():
                rclpy.shutdown(context=self._context)


def _take_all(sub: Ros2Subscription, out: list[Received]) -> None:
    take = sub.handle.take_message
    while (taken := take(sub.msg_type, True)) is not None:
        data, info = taken
        out.append(Received(sub.topic, data, info.get("publication_sequence_number")))


def _never_called(_msg) -> None:  # pragma: no cover - the wait set takes messages directly
    raise AssertionError("cosim subscriptions are read by the wait set, not by callbacks")


def no_signal_handlers():
    """rclpy's option for installing no signal handlers (the runtime owns SIGINT/SIGTERM)."""
    from rclpy.signals import SignalHandlerOptions

    return SignalHandlerOptions.NO
