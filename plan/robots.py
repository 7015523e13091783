"""Many robots in one world: the scenario's ``robots:`` section, checked and laid out.

A swarm scenario names one robot description (an MJCF like ``worlds/robot.xml``) and either
a ``count`` of robots placed from the scenario seed inside a ``region`` (at least
``clearance`` apart, clear of every obstacle, each with a goal in ``goal_region`` or its
start mirrored through the region's centre), or ``named`` robots with their starts and goals.
The world file is the arena only; every process builds the same world from it: the arena
with one copy of the description per robot attached at its start, every name (bodies,
joints, sites, actuators, sensors) prefixed ``ROBOT/`` (``robot_3/base_link``), so the TF
frames read from the bodies carry the REP-105 multi-robot prefix as they are.

Placing: plan/robot_placement.py (checked against the world by
descriptions/robot_layout.py); the swarm world: descriptions/swarm_world.py; node templates:
plan/templates.py.

Conventions (docs/tutorials/swarm.md): each robot's topics live under its namespace
(``/robot_3/odom``, ``/robot_3/scan``, ``/robot_3/cmd_vel``); ``/tf``, ``/tf_static``,
``/clock`` and cosim's own ``/cosim/...`` topics are shared. A node with ``for_each: robot``
becomes one node per robot named ``NAME@ROBOT`` (its own seed stream, as every node's seed
comes from its name) with every topic namespaced; the world node (physics, one MuJoCo
world: a class with ``every_robot``) declares its topics for one robot and serves every
robot's under its namespace (``per_robot``; its spec's ``robots`` lists them), one input per
robot. A scenario without a robots: section is a swarm of one unnamed robot.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from pathlib import Path

SHARED_TOPICS = ("/tf", "/tf_static", "/clock")


@dataclass(frozen=True)
class RobotPlacement:
    """One robot: its name (namespace and name prefix), start and goal as (x, y, yaw)."""

    name: str
    start: tuple[float, float, float]
    goal: tuple[float, float, float]
    enter_ns: int = 0  # when it enters the world (a scenario event's robot: later)
    leave_ns: int | None = None  # when an event deletes it; None: it stays to the end


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

    @property
    def at_start(self) -> RobotsLayout:
        """The layout of the robots in the world at time 0 (the world the run starts with)."""
        if all(r.enter_ns == 0 for r in self.robots):
            return self
        return replace(self, robots=tuple(r for r in self.robots if r.enter_ns == 0))

    @property
    def everyone(self) -> RobotsLayout:
        """The layout with every robot at time 0 (to read each robot's names from)."""
        if all(r.enter_ns == 0 and r.leave_ns is None for r in self.robots):
            return self
        return replace(self, robots=tuple(replace(r, enter_ns=0, leave_ns=None)
                                          for r in self.robots))

    def placement(self, name: str) -> RobotPlacement:
        """The robot named ``name``."""
        return next(r for r in self.robots if r.name == name)

    def goal_of(self, name: str) -> dict[str, float]:
        """The goal of robot ``name`` as the scenario's ``goal:`` would give it."""
        x, y, yaw = self.placement(name).goal
        return {"x": x, "y": y, "yaw": yaw, "position_tolerance": self.position_tolerance,
                "yaw_tolerance": self.yaw_tolerance}

    @property
    def needed(self) -> int:
        """How many robots must reach their goals for the run to succeed."""
        return max(1, math.ceil(self.success_fraction * len(self.robots) - 1e-9))


def namespaced(robot: str, topic: str) -> str:
    """``topic`` under robot's namespace: '/robot_3/scan'; shared topics stay as they are."""
    if topic in SHARED_TOPICS or topic.startswith("/cosim/"):
        return topic
    return f"/{robot}{topic}"


def per_robot(topics, robots: list[str] | None):
    """A world node's topics (a dict topic -> value or a set) as it serves ``robots``: each
    robot's own under its namespace, the shared ones once; as they are without robots."""
    if not robots or topics is None:
        return topics
    if isinstance(topics, dict):
        out = {}
        for topic, value in topics.items():
            out.update({namespaced(r, topic): value for r in robots})
        return out
    return {namespaced(r, topic) for topic in topics for r in robots}


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


def ros_identity(node_name: str) -> tuple[str, str]:
    """(name, namespace) of a cosim node as a ROS 2 node: 'control' -> ('control', '/'),
    'control@robot_3' -> ('control', '/robot_3'), as the robot's topics are namespaced.
    Characters a ROS 2 node name may not hold become '_'."""
    base, _, robot = node_name.partition("@")
    name = ros_name_chars(base)
    if name[:1].isdigit():
        name = f"_{name}"
    return name, f"/{robot}" if robot else "/"


def topic_token(node_name: str) -> str:
    """A node name as a part of a topic name (a topic may not hold '@'):
    'control@robot_3' -> 'control_at_robot_3'."""
    return node_name.replace("@", "_at_")


def prefixed(robot: str, name: str) -> str:
    """A name of the description as it is in the swarm world: 'robot_3/base_link'."""
    return f"{robot}/{name}"
