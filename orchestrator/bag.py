"""Merge what the nodes recorded into one rosbag2 directory in MCAP storage.

Nodes write their own outputs (``nodes.recording``) so recording never sits on the
lockstep path; this module runs after the run, whatever its outcome, and adds ``/clock``.
``rosbags`` writes the bag with full ROS 2 message definitions, so ``ros2 bag``,
Foxglove and the ``mcap`` readers open it.
"""

from __future__ import annotations

import heapq
from pathlib import Path

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from nodes.protocol import CLOCK_TOPIC, encode_clock
from nodes.recording import read_part

BAG_DIR = "bag"


def ros_type_name(msg_class: type) -> str:
    """'sensor_msgs/msg/LaserScan' for the rclpy class."""
    return f"{msg_class.__module__.split('.')[0]}/msg/{msg_class.__name__}"


def write_bag(scenario, run_dir: Path, ticks_run: int, finished: bool = True) -> Path | None:
    """Write ``<run dir>/bag`` from the node parts and the clock; None when nothing ran.

    A finished run keeps ticks ``0 .. ticks_run - 1`` only: nodes may have worked ahead
    of a stop decision (the pipeline window). A failed run keeps everything recorded."""
    parts = {name: run_dir / "parts" / f"{name}.rec" for name in scenario.schedule.order}
    parts = {name: path for name, path in parts.items() if path.exists()}
    if not parts and ticks_run == 0:
        return None
    typestore = get_typestore(Stores.ROS2_JAZZY)
    bag = run_dir / BAG_DIR
    rank = {name: i for i, name in enumerate(scenario.schedule.order)}
    streams = [((tick, rank[name], topic, data) for tick, topic, data in read_part(path))
               for name, path in parts.items()]
    last_tick = max(ticks_run - 1, 0)
    clock = ((k, -1, CLOCK_TOPIC, encode_clock(scenario.schedule.time_ns(k)))
             for k in range(ticks_run))
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {CLOCK_TOPIC: writer.add_connection(CLOCK_TOPIC, "rosgraph_msgs/msg/Clock",
                                                          typestore=typestore)}
        for topic, msg_class in sorted(scenario.topics.items()):
            connections[topic] = writer.add_connection(topic, ros_type_name(msg_class),
                                                       typestore=typestore)
        for tick, _, topic, data in heapq.merge(clock, *streams):
            if tick <= last_tick or (topic != CLOCK_TOPIC and not finished):
                writer.write(connections[topic], scenario.schedule.time_ns(tick), data)
    return bag
