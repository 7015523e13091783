"""The rclpy node a cosim-ros2 verb works through: its own context on the run's ROS domain
(--domain, ROS_DOMAIN_ID, or the run going on this machine: ``orchestrator.ros2cli.attach``),
hidden from node lists as ros2cli's are, and the graph queries the verbs share."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy


@contextmanager
def ros_session(domain: int | None) -> Iterator[tuple[Any, Any]]:
    """(node, executor) on ``domain`` (default: ROS_DOMAIN_ID, else 0); shut down after."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    # cosim's runs keep discovery on the machine unless told otherwise: so does the tool
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    context = rclpy.Context()
    if domain is None:
        rclpy.init(context=context)
    else:
        rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node(f"_cosim_ros2_{os.getpid()}", context=context,
                             start_parameter_services=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()


def spin_for(executor: Any, seconds: float) -> None:
    """Let discovery and callbacks run for ``seconds``."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=min(0.05, max(0.0, end - time.monotonic())))


def spin_until(executor: Any, done: Callable[[], bool], timeout: float | None) -> bool:
    """Spin until ``done()`` (True) or ``timeout`` seconds pass (False; None: never)."""
    end = None if timeout is None else time.monotonic() + timeout
    while not done():
        if end is not None and time.monotonic() >= end:
            return False
        executor.spin_once(timeout_sec=0.05)
    return True


def wait_for_topic_type(node: Any, executor: Any, topic: str, timeout: float | None,
                        note: Callable[[str], None]) -> str | None:
    """The type of ``topic`` once a publisher or subscriber is seen (None after timeout)."""
    start = time.monotonic()
    noted = False
    while True:
        types = dict(node.get_topic_names_and_types()).get(topic)
        if types:
            return types[0]
        waited = time.monotonic() - start
        if timeout is not None and waited >= timeout:
            return None
        if waited > 2 and not noted:
            note(f"waiting for {topic} to appear on ROS domain "
                 f"{node.context.get_domain_id()}...")
            noted = True
        executor.spin_once(timeout_sec=0.1)


def matching_qos(node: Any, topic: str, depth: int = 10) -> QoSProfile:
    """A subscription QoS every publisher of ``topic`` can serve: reliable only when they all
    are, transient-local (latched messages) only when they all are."""
    infos = node.get_publishers_info_by_topic(topic)
    reliable = bool(infos) and all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                                   for i in infos)
    latched = bool(infos) and all(
        i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
    return QoSProfile(depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                      else DurabilityPolicy.VOLATILE)


def hidden(name: str) -> bool:
    """Whether a graph name is hidden (a part that starts with '_'), as ros2cli hides them."""
    return any(part.startswith("_") for part in name.split("/"))


def print_names(names_and_types, show_types: bool, include_hidden: bool = False) -> None:
    """Print graph names sorted, as ros2cli's ``list`` verbs do: hidden ones only when asked,
    each with its types after it with ``show_types``."""
    for name, types in sorted(names_and_types):
        if hidden(name) and not include_hidden:
            continue
        print(f"{name} [{', '.join(types)}]" if show_types else name)
