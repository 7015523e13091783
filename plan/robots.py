"""Many robots in one world: the scenario's ``robots:`` section, checked and laid out.

A swarm scenario names one robot description (an MJCF like ``worlds/robot.xml``) and either
a ``count`` of robots placed from the scenario seed inside a ``region`` (at least
``clearance`` apart, clear of every obstacle, each with a goal in ``goal_region`` or its
start mirrored through the region's centre), or ``named`` robots with their starts and goals.
The world file is the arena only; every process builds the same world from it: the arena
with one copy of the description per robot attached at its start, every name (bodies,
joints, sites, actuators, sensors) prefixed ``ROBOT/`` (``robot_3/base_link``).

Namespaces (``robot_namespace``): with several robots each robot's topics live under its
namespace, its name unless ``named[].namespace`` gives another, and its TF frames carry the
REP-105 multi-robot prefix (``robot_3/base_link``). A lone robot lives at the root, as
robot_state_publisher and a one-robot Gazebo world publish it (``/cmd_vel``, ``/scan``,
``/joint_states``, frames ``odom`` and ``base_link``), unless its entry names a namespace.
Its MuJoCo names keep the ``ROBOT/`` prefix: only ROS-facing names drop it.

Placing: plan/robot_placement.py (checked against the world by
descriptions/robot_layout.py); the swarm world: descriptions/swarm_world.py; node templates:
plan/templates.py.

Conventions (docs/tutorials/swarm.md): each robot's topics live under its namespace
(``/robot_3/odom``, ``/robot_3/scan``, ``/robot_3/cmd_vel``); ``/tf``, ``/tf_static``,
``/clock`` and cosim's own ``/cosim/...`` topics are shared. A node with ``for_each: robot``
becomes one node per robot named ``NAME@ROBOT`` (its own seed stream, as every node's seed
comes from its name; the ROS node NAME in the robot's namespace) with every topic
namespaced; the world node (physics, one MuJoCo
world: a class with ``every_robot``) declares its topics for one robot and serves every
robot's under its namespace (``per_robot``; its spec's ``robots`` lists them), one input per
robot. A scenario without a robots: section is a swarm of one unnamed robot.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass, fields, replace
from pathlib import Path

SHARED_TOPICS = ("/tf", "/tf_static", "/clock")
BY_CLIENT = -1  # the enter_ns of a robot a client brings in (SpawnEntity): not known ahead


@dataclass(frozen=True)
class RobotPlacement:
    """One robot: its name (its MuJoCo name prefix, and its node instances' suffix), start
    and goal as (x, y, yaw), its ROS namespace ('' for the root: ``robot_namespace``)."""

    name: str
    start: tuple[float, float, float]
    goal: tuple[float, float, float]
    enter_ns: int = 0  # when it enters the world (a scenario event's robot: later)
    leave_ns: int | None = None  # when an event deletes it; None: it stays to the end
    description: Path | None = None  # its own description (an event's robot); None: the
    settings: str = ""  # layout's, read with these settings (descriptions.readers)
    base_body: str | None = None  # its own description's root body
    namespace: str | None = None  # its ROS namespace ('' the root); None: its name


@dataclass(frozen=True)
class RobotsLayout:
    """Every robot of the scenario, where it starts and where it goes, and the description."""

    description: Path
    base_body: str
    robots: tuple[RobotPlacement, ...]
    position_tolerance: float
    yaw_tolerance: float
    success_fraction: float
    settings: str = ""  # how its reader reads the description (descriptions.readers): the
    # scenario's robots.urdf or robots.usd as JSON, package folders absolute; '' for MJCF

    @property
    def names(self) -> list[str]:
        """The robots' names in order (those that enter during the run too)."""
        return [r.name for r in self.robots]

    @functools.cached_property  # made once: every robot's node asks (a walk of every robot)
    def at_start(self) -> RobotsLayout:
        """The layout of the robots in the world at time 0 (the world the run starts with)."""
        if all(r.enter_ns == 0 for r in self.robots):
            return self
        return replace(self, robots=tuple(r for r in self.robots if r.enter_ns == 0))

    @functools.cached_property  # made once, as at_start
    def everyone(self) -> RobotsLayout:
        """The layout with every robot at time 0 (to read each robot's names from)."""
        if all(r.enter_ns == 0 and r.leave_ns is None for r in self.robots):
            return self
        return replace(self, robots=tuple(replace(r, enter_ns=0, leave_ns=None)
                                          for r in self.robots))

    def placement(self, name: str) -> RobotPlacement:
        """The robot named ``name`` (KeyError where none is)."""
        return self._by_name[name]

    def __hash__(self) -> int:
        return self._hash

    @functools.cached_property
    def _hash(self) -> int:
        """The layout's hash, worked out once: the layout is the key of the process's caches
        of the swarm world (its model, mirror, arena), asked by every robot's node, and
        hashing a thousand robots' placements each time was a second of a thousand robots'
        start-up."""
        return hash(tuple(getattr(self, f.name) for f in fields(self)))

    def __getstate__(self) -> dict:
        """What a pickle keeps: not the hash, which is of this process (str hashes are
        salted per process) and is worked out again where it is unpickled, nor the layouts
        made from this one (made again where asked)."""
        return {k: v for k, v in self.__dict__.items()
                if k not in ("_hash", "at_start", "everyone")}

    @functools.cached_property
    def _by_name(self) -> dict[str, RobotPlacement]:
        """The robots by name, made once: a lookup per robot's node must not walk every
        robot (a thousand robots' nodes would take a million steps)."""
        return {r.name: r for r in self.robots}

    def source_of(self, name: str) -> tuple[Path, str]:
        """(description, reader settings) of robot ``name``: its own, or the layout's."""
        r = self.placement(name)
        return (self.description, self.settings) if r.description is None else (
            r.description, r.settings)

    def base_of(self, name: str) -> str:
        """The root body of robot ``name``'s description (unprefixed)."""
        return self.placement(name).base_body or self.base_body

    def namespace_of(self, name: str) -> str:
        """Robot ``name``'s ROS namespace ('' for the root): ``namespace_in``."""
        return namespace_in(self, name)

    def goal_of(self, name: str) -> dict[str, float]:
        """The goal of robot ``name`` as the scenario's ``goal:`` would give it."""
        x, y, yaw = self.placement(name).goal
        return {"x": x, "y": y, "yaw": yaw, "position_tolerance": self.position_tolerance,
                "yaw_tolerance": self.yaw_tolerance}

    @property
    def needed(self) -> int:
        """How many robots must reach their goals for the run to succeed (of those an
        event does not take out of the run; a robot a client may bring in is extra)."""
        staying = sum(r.leave_ns is None and r.enter_ns != BY_CLIENT for r in self.robots)
        return max(1, math.ceil(self.success_fraction * staying - 1e-9))


def robot_namespace(section, robot: str) -> str:
    """The ROS namespace of robot ``robot`` of the scenario's ``robots:`` section (a
    ``plan.model.RobotsSpec``, or None): the entry's ``namespace`` where it names one, else
    the robot's name when the section has several robots (or does not place this one), else
    '' (a lone robot lives at the root)."""
    if section is None:
        return robot
    entries = section.named or []
    entry = next((e for e in entries if e.name == robot), None)
    if entry is not None and entry.namespace is not None:
        return entry.namespace
    several = (section.count or len(entries)) > 1
    placed = entry is not None or (section.named is None and section.count is not None and
                                   _is_counted(robot, section.name_prefix, section.count))
    return robot if several or not placed else ""


def _is_counted(robot: str, prefix: str, count: int) -> bool:
    """Whether ``robot`` is one of ``{prefix}_0`` .. ``{prefix}_{count - 1}`` (read from the
    name, not by making every name: once per robot of every world node's input)."""
    head, number = f"{prefix}_", robot[len(prefix) + 1:]
    return (robot.startswith(head) and number.isascii() and number.isdigit()
            and str(int(number)) == number and int(number) < count)


def namespace_in(layout: RobotsLayout | None, robot: str | None) -> str:
    """The ROS namespace of robot ``robot`` of a resolved scenario whose ``robots:`` section
    is ``layout`` (None without one), the one reading of it once the robots are placed: ''
    for no robot (a world node, nav's unnamed robot); the robot's name where no layout
    places it; else what placement gave it (``robot_namespace``: '' a lone robot at the
    root, its entry's namespace, its name in a swarm)."""
    if not robot:
        return ""
    placed = None if layout is None else layout._by_name.get(robot)
    return robot if placed is None or placed.namespace is None else placed.namespace


def robot_namespaces(section, robots: list[str] | None) -> list[str] | None:
    """``robot_namespace`` of each of ``robots`` (a world node's spec.robots); None without.
    The plan asks this of the world node's spec once per input of every robot's node: the
    answer for the same section and robots is kept (the last few)."""
    if robots is None:
        return None
    key = (id(section), tuple(robots))
    held = _NAMESPACES.get(key)
    if held is None or held[0] is not section:
        entries = {} if section is None else {  # the first entry of a name, as next() finds
            e.name: e for e in reversed(section.named or [])}
        held = (section, [_namespace_of(section, entries, r) for r in robots])
        if len(_NAMESPACES) >= 8:
            _NAMESPACES.clear()
        _NAMESPACES[key] = held
    return list(held[1])


_NAMESPACES: dict[tuple[int, tuple[str, ...]], tuple[object, list[str]]] = {}
"""robot_namespaces' answers by (the section's id, the robots); the section is kept with
its answer, so its id cannot be reused while the answer is held."""


def _namespace_of(section, entries: dict, robot: str) -> str:
    """``robot_namespace`` with the section's named entries by name (``entries``)."""
    if section is None:
        return robot
    entry = entries.get(robot)
    if entry is not None and entry.namespace is not None:
        return entry.namespace
    several = (section.count or len(section.named or [])) > 1
    placed = entry is not None or (section.named is None and section.count is not None and
                                   _is_counted(robot, section.name_prefix, section.count))
    return robot if several or not placed else ""


def frame_prefix(namespace: str) -> str:
    """The TF frame prefix of a robot in ``namespace``: 'robot_3/'; '' at the root."""
    return f"{namespace}/" if namespace else ""


def namespaced(namespace: str, topic: str) -> str:
    """``topic`` under a robot's namespace: '/robot_3/scan'; as it is at the root (''), and
    shared topics stay as they are."""
    if not namespace or topic in SHARED_TOPICS or topic.startswith("/cosim/"):
        return topic
    return f"/{namespace}{topic}"


def per_robot(topics, namespaces: list[str] | None):
    """A world node's topics (a dict topic -> value or a set) as it serves robots in
    ``namespaces``: each robot's own under its namespace, the shared ones once; as they are
    without robots (or for one robot at the root)."""
    if not namespaces or topics is None:
        return topics
    if isinstance(topics, dict):
        out = {}
        for topic, value in topics.items():
            out.update({namespaced(r, topic): value for r in namespaces})
        return out
    return {namespaced(r, topic) for topic in topics for r in namespaces}


def merged_names(given: list[tuple[str, dict]]) -> dict:
    """The robot description's names that the nodes' parameters give, (node name, its
    ``description_names``) each, merged; a ValueError naming both nodes where two name one
    thing differently."""
    merged: dict[str, tuple[str, object]] = {}
    for node, names in given:
        for key, value in names.items():
            value = tuple(value) if isinstance(value, list) else value
            if key in merged and merged[key][1] != value:
                raise ValueError(f"nodes {merged[key][0]!r} and {node!r} name the robot's "
                                 f"{key} differently: {merged[key][1]!r} and {value!r}")
            merged.setdefault(key, (node, value))
    return {key: value for key, (_, value) in merged.items()}


def robot_of(node_name: str) -> str | None:
    """The robot of a node instance ('control@robot_3' -> 'robot_3'), None for others."""
    return node_name.partition("@")[2] or None


def ros_name_chars(text: str) -> str:
    """``text`` with every character a ROS 2 node name may not hold replaced by '_'."""
    return re.sub(r"[^A-Za-z0-9_]", "_", text)


def ros_identity(node_name: str, namespace: str | None = None) -> tuple[str, str]:
    """(name, namespace) of a cosim node as a ROS 2 node: 'control' -> ('control', '/'),
    'control@robot_3' -> ('control', '/robot_3'), as the robot's topics are namespaced;
    ``namespace`` is the robot's where it is not its name ('' at the root: '/').
    Characters a ROS 2 node name may not hold become '_'."""
    base, _, robot = node_name.partition("@")
    name = ros_name_chars(base)
    if name[:1].isdigit():
        name = f"_{name}"
    namespace = robot if namespace is None else namespace
    return name, f"/{namespace}" if namespace else "/"


def topic_token(node_name: str) -> str:
    """A node name as a part of a topic name (a topic may not hold '@'):
    'control@robot_3' -> 'control_at_robot_3'."""
    return node_name.replace("@", "_at_")


def prefixed(robot: str, name: str) -> str:
    """A name of the description as it is in the swarm world: 'robot_3/base_link'."""
    return f"{robot}/{name}"
