"""The run's rosbag2 (MCAP): written here from what the nodes recorded, and read back here
for the API, the digest diff, the report picture and the USD export.

Nodes write their own outputs (``runtime.recording``) so recording never sits on the
lockstep path; this module runs after the run, whatever its outcome, and adds ``/clock``.
``rosbags`` writes the bag with full ROS 2 message definitions, so ``ros2 bag``,
Foxglove and the ``mcap`` readers open it.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from orchestrator.proxies.arrivals_record import arrival_topics
from plan.ros_types import message_class, ros_type
from plan.run_paths import RunPaths
from runtime.protocol import CLOCK_TOPIC, encode_clock
from runtime.recording import read_part

if TYPE_CHECKING:
    from plan.scenario import Scenario

UNSPECIFIED = QosTime(0, 0)  # the middleware's default (infinite), as rosbag2 reads it
LATCHED_QOS = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE,
                  QosDurability.TRANSIENT_LOCAL, UNSPECIFIED, UNSPECIFIED,
                  QosLiveliness.AUTOMATIC, UNSPECIFIED, False)
"""The offered QoS recorded for a latched topic (/tf_static): what tf2's static broadcaster
offers, so that ``ros2 bag play`` republishes it latched and Foxglove treats it so."""


def write_bag(scenario: Scenario, run_dir: Path, ticks_run: int, finished: bool = True
              ) -> Path | None:
    """Write ``<run dir>/bag`` from the node parts and the clock; None when nothing ran.

    A finished run keeps ticks ``0 .. ticks_run - 1`` only: nodes may have worked ahead
    of a stop decision (the pipeline window). A failed run keeps everything recorded."""
    paths = RunPaths(run_dir)
    parts = {name: paths.part(name) for name in scenario.schedule.order}
    parts = {name: path for name, path in parts.items() if path.exists()}
    if not parts and ticks_run == 0:
        return None
    typestore = get_typestore(Stores.ROS2_JAZZY)
    register_installed(typestore, scenario.topics.values())  # arrivals: external topics' types
    bag = paths.bag
    rank = {name: i for i, name in enumerate(scenario.schedule.order)}
    streams = [((tick, rank[name], topic, data) for tick, topic, data in read_part(path))
               for name, path in parts.items()]
    last_tick = max(ticks_run - 1, 0)
    clock = ((k, -1, CLOCK_TOPIC, encode_clock(scenario.schedule.time_ns(k)))
             for k in range(ticks_run))
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {CLOCK_TOPIC: writer.add_connection(CLOCK_TOPIC, "rosgraph_msgs/msg/Clock",
                                                          typestore=typestore)}
        latched = scenario.latched_topics
        for topic, msg_class in sorted({**scenario.topics, **arrival_topics(scenario)}.items()):
            qos = [LATCHED_QOS] if topic in latched else []
            connections[topic] = writer.add_connection(topic, ros_type(msg_class),
                                                       typestore=typestore,
                                                       offered_qos_profiles=qos)
        for tick, _, topic, data in heapq.merge(clock, *streams):
            if tick <= last_tick or (topic != CLOCK_TOPIC and not finished):
                writer.write(connections[topic], scenario.schedule.time_ns(tick), data)
    return bag


IDL_TO_MSG = {"boolean": "bool", "octet": "byte", "double": "float64", "float": "float32",
              "long double": "float64"}


def register_installed(typestore, classes: Iterable[type]) -> None:
    """Teach ``typestore`` the installed message types it lacks (simulation_interfaces,
    a foreign program's own package, ...), from the rclpy classes' field lists, so the bag
    carries their definitions like any other (field names and types; not constants)."""
    from rosbags.typesys import get_types_from_msg

    todo = [c for c in classes]
    while todo:
        cls = todo.pop()
        name = ros_type(cls)
        if name in typestore.fielddefs:
            continue
        lines = []
        for field, idl in cls.get_fields_and_field_types().items():
            lines.append(f"{_msg_type(idl, todo)} {field}")
        types = get_types_from_msg("\n".join(lines), name)
        if name not in types:  # rosbags files 'pkg/srv/Name_Request' under 'pkg/srv/msg/...'
            types = {name: next(iter(types.values()))}
        typestore.register(types)


def _msg_type(idl: str, todo: list[type]) -> str:
    """An rosidl field type ('sequence<double, 3>', 'geometry_msgs/Pose', 'double[9]') as
    .msg text; a message type it names is queued for registration."""
    import importlib

    if idl.startswith("sequence<"):
        inner, _, bound = idl[9:-1].partition(", ")
        return f"{_msg_type(inner, todo)}[{'<=' + bound if bound else ''}]"
    if idl.endswith("]"):
        inner, _, size = idl[:-1].partition("[")
        return f"{_msg_type(inner, todo)}[{size}]"
    if "/" in idl:
        package, _, type_name = idl.partition("/")
        todo.append(getattr(importlib.import_module(f"{package}.msg"), type_name))
        return f"{package}/msg/{type_name}"
    return IDL_TO_MSG.get(idl, idl)


class BagReader:
    """Reads a run's bag: which topics it has, their raw messages in log order, and the
    messages decoded (as rosbags objects, or as the rclpy classes the nodes published).

        with BagReader(run.bag) as bag:
            for topic, stamp_ns, raw in bag.raw(["/odom"]):
                ...
    """

    def __init__(self, bag: Path):
        from rosbags.highlevel import AnyReader

        self.path = Path(bag)
        self._reader = AnyReader([self.path], default_typestore=get_typestore(Stores.ROS2_JAZZY))

    def __enter__(self) -> BagReader:
        self._reader.open()
        self._types = {c.topic: c.msgtype for c in self._reader.connections}
        self._counts: dict[str, int] = {}
        for conn in self._reader.connections:
            self._counts[conn.topic] = self._counts.get(conn.topic, 0) + conn.msgcount
        return self

    def __exit__(self, *_exc) -> None:
        self._reader.close()

    @property
    def counts(self) -> dict[str, int]:
        """Messages recorded per topic."""
        return dict(self._counts)

    def msgtype(self, topic: str) -> str:
        """The ROS type of a topic, e.g. 'nav_msgs/msg/Odometry'; KeyError naming the topics."""
        if topic not in self._types:
            raise KeyError(f"{topic} was not recorded; topics: {', '.join(sorted(self._types))}")
        return self._types[topic]

    def raw(self, topics: Iterable[str] | None = None, exclude: Iterable[str] = (),
            start: int | None = None, stop: int | None = None
            ) -> Iterator[tuple[str, int, bytes]]:
        """(topic, log time in ns, CDR bytes) of the chosen topics (all but ``exclude`` when
        None), in log order; only those logged at or after ``start`` and before ``stop``
        (ns) when given."""
        chosen = None if topics is None else set(topics)
        skipped = set(exclude)
        conns = [c for c in self._reader.connections
                 if (chosen is None or c.topic in chosen) and c.topic not in skipped]
        if not conns:
            return
        for conn, stamp, raw in self._reader.messages(connections=conns, start=start,
                                                      stop=stop):
            yield conn.topic, stamp, raw

    def deserialize(self, raw: bytes, topic: str) -> Any:
        """A message of ``topic`` as a rosbags object (no rclpy needed)."""
        return self._reader.deserialize(raw, self._types[topic])

    def messages(self, topic: str, msg_class: type | None = None) -> Iterator[tuple[int, Any]]:
        """(log time in ns, rclpy message) of ``topic``, decoded by cosim's generated code into
        ``msg_class`` (default: the class its ROS type names)."""
        from runtime.cdr.decode import decode

        cls = msg_class or message_class(self.msgtype(topic))
        for _, stamp, raw in self.raw([topic]):
            yield stamp, decode(raw, cls)


