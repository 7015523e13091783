"""Objects that enter and leave a running simulation: a scenario's ``events:`` list.

Each event happens at a time on a tick of the physics node: ``spawn`` adds an object (a
box, cylinder, sphere or mesh; static, or free with a mass) to the world, ``delete``
takes one that an earlier event spawned out again. Every node that holds a copy of the
world (physics, the sensors' mirrors) applies the same events at the same tick boundary,
straight from the plan, so a run with events is as deterministic as one without. This
module holds the schema and the checks that need no world loaded; the world's side (names
taken, obstacles, robots) is ``object_problems``, given what the world loader reads out of
the world (``WorldObjects``).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from typing import Annotated, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, model_validator

from plan.description_spec import UrdfSpec, UsdSpec
from plan.obstacles import Obstacle, place_problem
from plan.timeutil import Ns, format_ns, parse_duration_ns

SHAPES = ("box", "cylinder", "sphere", "mesh")
SIZES = {"box": 3, "cylinder": 2, "sphere": 1}  # how many numbers ``size`` holds per shape
SIZE_HELP = {"box": "[x, y, z]: the full lengths in metres", "cylinder": "[radius, length]",
             "sphere": "[radius]"}


_ZERO = re.compile(r"\s*0+(\.0*)?\s*(s|ms|us|ns)?\s*")


def parse_time_ns(value: object) -> int:
    """A point in simulated time: 0, or a duration ('5s', '200ms') from the start, in ns."""
    if value == 0 or (isinstance(value, str) and _ZERO.fullmatch(value)):
        return 0  # '0', '0s', '0ms': the first tick
    return parse_duration_ns(value)


TimeNs = Annotated[int, BeforeValidator(parse_time_ns)]
EventName = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$")]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ObjectPose(_Strict):
    """Where an object is put: position in metres, heading in radians."""

    x: float = Field(description="a number, in metres")
    y: float = Field(description="a number, in metres")
    z: float | None = Field(None, description="its centre's height in metres; default: "
                            "resting on the floor (a mesh: its file's origin at z = 0)")
    yaw: float = Field(0.0, description="a number, in radians")


class ObjectSpec(_Strict):
    """An object to put into the world: a box, cylinder, sphere or mesh, static (welded to
    the world: an obstacle) or free (it falls, slides and can be pushed) with a mass."""

    name: EventName = Field(description="letters, digits and _; its body and geom name in "
                            "the world, unique among the world's and the live objects'")
    shape: Literal["box", "cylinder", "sphere", "mesh"] = Field(
        description="box, cylinder (upright), sphere or mesh")
    size: tuple[float, ...] = Field((), description="box: [x, y, z] full lengths in metres; "
                                    "cylinder: [radius, length]; sphere: [radius]; not "
                                    "for a mesh (use scale)")
    mesh: str | None = Field(None, description="shape mesh: the mesh file (STL, OBJ, "
                             "COLLADA; relative to the scenario file)")
    scale: tuple[float, float, float] = Field((1.0, 1.0, 1.0), description="shape mesh: "
                                              "scale per axis (0.001: a mesh in millimetres)")
    pose: ObjectPose = Field(description="where it is put")
    static: bool = Field(True, description="true: welded to the world (an obstacle); false: "
                         "a free body with a mass")
    mass: float | None = Field(None, gt=0, description="kg; required when static is false")
    rgba: tuple[float, float, float, float] = Field((0.3, 0.5, 0.8, 1.0), description=(
        "colour as the camera sees it, four numbers 0..1"))

    @model_validator(mode="after")
    def _consistent(self) -> ObjectSpec:
        if self.shape == "mesh":
            if self.mesh is None:
                raise ValueError("shape mesh needs mesh: the mesh file")
            if self.size:
                raise ValueError("a mesh takes scale, not size")
        else:
            if self.mesh is not None:
                raise ValueError(f"mesh: is for shape mesh, not {self.shape}")
            want = SIZES[self.shape]
            if len(self.size) != want:
                raise ValueError(f"a {self.shape} needs size {SIZE_HELP[self.shape]} "
                                 f"({want} number{'s' * (want > 1)}), got {list(self.size)}")
            if any(not s > 0 for s in self.size):
                raise ValueError(f"every size must be greater than 0, got {list(self.size)}")
        if any(not s > 0 for s in self.scale):
            raise ValueError(f"every scale must be greater than 0, got {list(self.scale)}")
        if self.static and self.mass is not None:
            raise ValueError("a static object has no mass; static: false for a free one")
        if not self.static and self.mass is None:
            raise ValueError("a free object (static: false) needs mass: kg")
        return self

    @property
    def half_height(self) -> float | None:
        """Half its height (how far its centre stands above the floor); None for a mesh,
        whose extent the world loader reads."""
        if self.shape == "box":
            return self.size[2] / 2
        if self.shape == "cylinder":
            return self.size[1] / 2
        if self.shape == "sphere":
            return self.size[0]
        return None

    @property
    def footprint_radius(self) -> float | None:
        """The radius of the circle that holds it seen from above (None for a mesh)."""
        if self.shape == "box":
            return math.hypot(self.size[0], self.size[1]) / 2
        if self.shape in ("cylinder", "sphere"):
            return self.size[0]
        return None


class RobotPose(_Strict):
    """A robot's planar pose: position in metres, heading in radians."""

    x: float = Field(description="a number, in metres")
    y: float = Field(description="a number, in metres")
    yaw: float = Field(0.0, description="a number, in radians")


class RobotEntry(_Strict):
    """A robot that enters the running world: a copy of the ``robots:`` section's
    description, or of its own, under its own name (its namespace), with every ``for_each:
    robot`` node of the scenario (planned at launch, dormant until it enters;
    plan/robots.py)."""

    name: EventName = Field(description="letters, digits and _; its namespace, unique among "
                            "the robots and objects")
    start: RobotPose = Field(description="where it enters")
    goal: RobotPose = Field(description="where it must get to")
    description: str | None = Field(None, description="its own description (MJCF, URDF, "
                                    "xacro or USD), relative to this file; default: the "
                                    "robots: section's")
    urdf: UrdfSpec | None = Field(None, description="how its URDF or xacro description is "
                                  "read, as robots.urdf")
    usd: UsdSpec | None = Field(None, description="how its USD description is read, as "
                                "robots.usd")


class EventSpec(_Strict):
    """One thing that happens to the world at a time: an object spawned, a robot entering,
    or either taken out again."""

    at: TimeNs = Field(description="when, on a tick of the physics node: 0 or a duration "
                       "from the start such as '5s'")
    spawn: ObjectSpec | None = Field(None, description="an object to put into the world")
    robot: RobotEntry | None = Field(None, description="a robot to bring into the world "
                                     "(the robots: section's description), e.g. {name: late, "
                                     "start: {x: 1, y: 0}, goal: {x: -2, y: 0}}")
    delete: EventName | None = Field(None, description="the name of an object or robot an "
                                     "earlier event spawned, to take out of the world")

    @model_validator(mode="after")
    def _one_thing(self) -> EventSpec:
        if sum(x is not None for x in (self.spawn, self.robot, self.delete)) != 1:
            raise ValueError("give exactly one of spawn, robot and delete")
        return self

    @property
    def name(self) -> str:
        """The object or robot the event is about."""
        if self.spawn is not None:
            return self.spawn.name
        return self.robot.name if self.robot is not None else self.delete


@dataclass(frozen=True)
class WorldObjects:
    """What the event checks need of a loaded world: every name an object may not take
    (bodies and geoms), the static obstacles, and what moves at the start (robots, loose
    objects) as discs at their first positions."""

    names: frozenset[str]
    obstacles: tuple[Obstacle, ...]
    movers: tuple[Obstacle, ...]
    robots: frozenset[str] = frozenset()  # the robots: section's names (namespaces)


Problem = tuple[str, str, str]  # (key, problem, accepted)


def timing_problems(events: list[EventSpec], physics_period_ns: Ns | None, duration_ns: int
                    ) -> list[Problem]:
    """Each event's time is on a tick of the physics node, within the run; events are
    listed in time order."""
    out: list[Problem] = []
    if events and physics_period_ns is None:
        return [("events", "the scenario has events but no physics node publishes "
                 "/cosim/world_state to apply them.", "a physics node, or no events.")]
    last = 0
    for i, event in enumerate(events):
        key = f"events[{i}] ({event.name}).at"
        if event.at > duration_ns:
            out.append((key, f"{format_ns(event.at)} is after the run's end "
                        f"({format_ns(duration_ns)}).", "a time within the duration."))
        elif event.at % physics_period_ns:
            before = event.at // physics_period_ns * physics_period_ns
            out.append((key, f"{format_ns(event.at)} is not on a tick of the physics node "
                        f"(period {format_ns(physics_period_ns)}).", "a multiple of its "
                        f"period, e.g. {format_ns(before)} or "
                        f"{format_ns(before + physics_period_ns)}."))
        if event.at < last:
            out.append((key, f"{format_ns(event.at)} comes before the event above it "
                        f"({format_ns(last)}).", "events listed in time order."))
        last = max(last, event.at)
    return out


def object_problems(events: list[EventSpec], world: WorldObjects) -> list[Problem]:
    """Names and places against the world: a spawn's name is not the world's nor a live
    object's; a robot's name enters once (not again after its delete: its nodes are planned
    for one window); a delete names a live object (not a part of the world); a static object does
    not stand inside an obstacle or a static object already there, nor, at time 0, inside
    a robot or loose object at its start."""
    out: list[Problem] = []
    live: dict[str, tuple[int, ObjectSpec | None]] = {}  # None: a robot
    left: dict[str, int] = {}  # a robot taken out -> the delete's index
    for i, event in enumerate(events):
        key = f"events[{i}] ({event.name})"
        if event.robot is not None:
            name = event.robot.name
            if name == "world" or name in world.names or name in world.robots:
                out.append((f"{key}.robot.name", f"{name!r} is already a robot, body or "
                            "geom of the world.", "a name the world does not use."))
            elif name in left:  # its nodes are planned for one stay (one window)
                out.append((f"{key}.robot.name", f"{name!r} left the world at "
                            f"events[{left[name]}]; a robot's name enters once (its nodes "
                            "are planned for one stay in the world).", f"a name of its own "
                            f"for the robot that comes back, e.g. {name}_2."))
            elif name in live:
                out.append((f"{key}.robot.name", f"{name!r} is still in the world "
                            f"(events[{live[name][0]}] spawned it).",
                            "another name, or delete the first one before."))
            elif problem := _robot_place_problem(event, world, events[:i], live):
                out.append((f"{key}.robot.start", problem, "a start clear of the world's "
                            "obstacles and of the robots entering with it."))
            live.setdefault(name, (i, None))
            continue
        if event.delete is not None:
            if event.delete in live:
                if live.pop(event.delete)[1] is None:
                    left[event.delete] = i
            elif event.delete == "world" or event.delete in world.names:
                out.append((f"{key}.delete", f"{event.delete!r} is part of the world file; "
                            "only objects an event spawned can be deleted.",
                            _live_help(live)))
            else:
                out.append((f"{key}.delete", f"no object named {event.delete!r} is in the "
                            "world at that time.", _live_help(live)))
            continue
        obj = event.spawn
        if obj.name == "world" or obj.name in world.names:
            out.append((f"{key}.spawn.name", f"{obj.name!r} is already a body or geom of "
                        "the world.", "a name the world does not use."))
        elif obj.name in live:
            out.append((f"{key}.spawn.name", f"{obj.name!r} is still in the world "
                        f"(events[{live[obj.name][0]}] spawned it).",
                        "another name, or delete the first one before."))
        else:
            problem = _place_problem(obj, event.at, world, [o for _, o in live.values()])
            if problem:
                out.append((f"{key}.spawn.pose", problem, "a place clear of the world's "
                            "obstacles and of what stands there then."))
        live.setdefault(obj.name, (i, obj))
    return out


def _place_problem(obj: ObjectSpec, at_ns: int, world: WorldObjects,
                   live: list[ObjectSpec]) -> str | None:
    """Why ``obj`` cannot stand at its pose (inside something), or None. Only what can be
    known when the scenario loads: static things, and movers at time 0."""
    radius = obj.footprint_radius
    if radius is None:
        return None  # a mesh's extent is the world loader's to read; not checked
    x, y = obj.pose.x, obj.pose.y
    z = obj.pose.z if obj.pose.z is not None else obj.half_height
    band = (z - obj.half_height, z + obj.half_height)
    inside = [o for o in world.obstacles
              if o.z_range[1] > band[0] and o.z_range[0] < band[1]
              and o.distance(x, y) < -1e-9]
    if inside:
        return f"({x:g}, {y:g}) is inside obstacle {inside[0].name!r} ({inside[0].kind})."
    for other in live:
        if other is not None and other.static and other.footprint_radius is not None:
            gap = math.hypot(x - other.pose.x, y - other.pose.y)
            if gap < other.footprint_radius:
                return f"({x:g}, {y:g}) is inside object {other.name!r}."
    if at_ns == 0:
        for mover in world.movers:
            if mover.distance(x, y) < radius:
                return (f"({x:g}, {y:g}) overlaps {mover.name!r} where it starts "
                        f"({mover.centre[0]:g}, {mover.centre[1]:g}).")
    return None


def _robot_place_problem(event: EventSpec, world: WorldObjects, before: list[EventSpec],
                         live: dict) -> str | None:
    """Why a robot cannot enter at its start, or None: inside or too near an obstacle, or
    overlapping a robot that enters at the same time (or, at time 0, one already there).
    A robot's size is taken as the largest of the robots the world starts with."""
    radius = max((m.radius for m in world.movers if m.radius), default=0.2)
    x, y = event.robot.start.x, event.robot.start.y
    if problem := place_problem(list(world.obstacles), x, y, radius):
        return problem + "."
    others = [(e.robot.name, e.robot.start.x, e.robot.start.y) for e in before
              if e.robot is not None and e.at == event.at and e.robot.name in live]
    if event.at == 0:
        others += [(m.name, *m.centre) for m in world.movers]
    for name, ox, oy in others:
        if math.hypot(x - ox, y - oy) < 2 * radius:
            return f"({x:g}, {y:g}) overlaps {name!r} ({ox:g}, {oy:g}) as it enters."
    return None


def _live_help(live: dict[str, tuple[int, ObjectSpec]]) -> str:
    if not live:
        return "no object is spawned before this event; spawn one first."
    return f"one of the objects in the world then: {', '.join(sorted(live))}."


def physics_period(topics_by_node: dict[str, dict[str, type]], periods: dict[str, Ns]
                   ) -> Ns | None:
    """The period of the node that publishes /cosim/world_state (physics), or None."""
    for name, topics in topics_by_node.items():
        if "/cosim/world_state" in topics:
            return periods[name]
    return None


def robot_windows(events: list[EventSpec]) -> dict[str, tuple[int, int | None]]:
    """Each robot an event brings in: [the time it enters, the time a later event deletes
    it (None: it stays to the end)) in ns."""
    out: dict[str, tuple[int, int | None]] = {}
    for event in events:
        if event.robot is not None:
            out.setdefault(event.robot.name, (event.at, None))
        elif event.delete in out and out[event.delete][1] is None:
            out[event.delete] = (out[event.delete][0], event.at)
    return out


def edit_event(item: dict) -> EventSpec:
    """One edit a client asked for (``{"spawn": {...}}`` or ``{"delete": name}``) as an
    event of no particular time: it happens at the tick it enters."""
    return EventSpec.model_validate({"at": 0, **item})


def edits_text(edits: list[EventSpec]) -> str:
    """Edits as the /cosim/world_edits message carries them: a JSON list, each as
    ``edit_event`` reads it (stable text: sorted keys, no spaces)."""
    return json.dumps([e.model_dump(exclude={"at"}, exclude_none=True, mode="json")
                       for e in edits], sort_keys=True, separators=(",", ":"))


def parse_edits(text: str) -> list[EventSpec]:
    """The edits a /cosim/world_edits message carries (none for an empty message)."""
    return [edit_event(item) for item in json.loads(text)] if text else []
