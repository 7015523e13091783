"""SpawnEntity and DeleteEntity for objects (issue 49): a request is checked here, against
the world and what is in it at the next tick boundary, and an accepted one becomes part
of the /cosim/world_edits message (std_msgs/String: every edit accepted so far, as JSON,
``plan.events.edits_text``) put into the run's external arrivals. It enters at the
external node's next activation, is recorded (``--replay`` feeds it back), and the
physics node applies each edit once (``nodes.physics.world_events.LiveWorld``), telling
the sensor nodes' mirrors in every world state what is in the world.
"""

from __future__ import annotations

import math
import threading

import numpy as np
from simulation_interfaces.msg import Result
from simulation_interfaces.srv import SpawnEntity
from std_msgs.msg import String

from orchestrator.ros_surface.simcontrol import RunControl
from orchestrator.ros_surface.spawn_resources import Refused, requested_object
from orchestrator.ros_surface.spawnables import outside
from plan.events import EventSpec, ObjectSpec, edit_event, edits_text, object_problems
from plan.interactive import WORLD_EDITS_TOPIC
from plan.obstacles import Obstacle
from plan.scenario import EXTERNAL_NAME, Scenario
from plan.timeutil import tick_time_ns
from runtime.arrivals import Arrivals

R = SpawnEntity.Response


class ObjectSpawner:
    """The objects clients put into the run and take out of it."""

    def __init__(self, scenario: Scenario, control: RunControl, arrivals: Arrivals, topic: str,
                 robot=None):
        self.scenario, self.control, self.arrivals, self.topic = (scenario, control,
                                                                  arrivals, topic)
        self.robot = robot  # orchestrator.ros_surface.sim_entities.RobotEntity, or None
        self.edits: list[EventSpec] = []
        self.external_period = scenario.schedule.periods.get(EXTERNAL_NAME, 1)
        self._world = None
        self._lock = threading.Lock()
        control.reset_listeners.append(self.forget)
        from orchestrator.ros_surface.robot_spawn import RobotSlots

        self.robots = RobotSlots(scenario, control, self._put_robot, self.world)

    def _put_robot(self, edit: EventSpec) -> None:
        """A robot's edit, admitted by the lockstep at a tick boundary: it enters now."""
        with self._lock:
            self.edits.append(edit)
            self.arrivals.put(self.topic, String(data=edits_text(self.edits)))

    def forget(self) -> None:
        """The run was reset: the world is the scenario's again."""
        with self._lock:
            self.edits = []

    def world(self):
        """The world's names, obstacles and movers (``plan.events.WorldObjects``), once."""
        if self._world is None:
            from descriptions.world_edits import world_objects
            from nodes.physics.world import load_model

            self._world = world_objects(load_model(self.scenario.world, self.scenario.robots))
        return self._world

    def live(self) -> dict[str, ObjectSpec]:
        """The objects in the world at the next tick boundary: the scenario's events due by
        then, and the edits accepted so far."""
        now = tick_time_ns(self.control.boundary, self.scenario.tick_ns)
        out: dict[str, ObjectSpec] = {}
        for event in [e for e in self.scenario.model.events if e.at <= now] + self.edits:
            if event.spawn is not None:
                out[event.name] = event.spawn
            else:
                out.pop(event.name, None)
        return out

    def static_obstacles(self) -> list[Obstacle]:
        """The static objects in the world at the next boundary, as obstacles seen from
        above (a mesh's extent is not known here: left out)."""
        out = []
        for obj in self.live().values():
            radius = obj.footprint_radius
            if not obj.static or radius is None:
                continue
            z = obj.pose.z if obj.pose.z is not None else obj.half_height
            band = (z - obj.half_height, z + obj.half_height)
            common = dict(name=obj.name, geom=-1, kind=obj.shape, z_range=band,
                          centre=(obj.pose.x, obj.pose.y))
            if obj.shape == "box":
                hx, hy = obj.size[0] / 2, obj.size[1] / 2
                c, s = math.cos(obj.pose.yaw), math.sin(obj.pose.yaw)
                corners = [(obj.pose.x + c * x - s * y, obj.pose.y + s * x + c * y)
                           for x, y in ((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy))]
                out.append(Obstacle(polygon=np.array(corners), **common))
            else:
                out.append(Obstacle(radius=radius, **common))
        return out

    def spawn(self, request: SpawnEntity.Request) -> tuple[int, str, str]:
        """(result code, message, entity name) of a SpawnEntity request; an accepted one is
        put into the run."""
        if (answer := self.robots.spawn(request)) is not None:  # a planned robot's file
            return answer
        if request.entity_namespace.strip("/"):
            return (R.NAMESPACE_INVALID, f"entity_namespace {request.entity_namespace!r}: "
                    "objects have no topics (a robot enters through the scenario's "
                    "events:); leave it empty.", "")
        try:  # a file the client names: only the scenario's spawnables
            given, obj = requested_object(request, lambda source: outside(self.scenario,
                                                                          source))
        except Refused as exc:
            return exc.code, str(exc), ""
        from descriptions.world_edits import object_problem

        problem = object_problem(obj)
        if problem:
            return R.UNSUPPORTED_ASSETS, f"MuJoCo cannot make the object: {problem}", ""
        with self._lock:
            live = self.live()
            taken = self.world().names | set(live) | {"world"}
            name = given
            if not name or name in taken:
                if not request.allow_renaming:
                    if not name:
                        return R.NAME_INVALID, ("no name given, and the resource names none; "
                                                "give one or allow_renaming."), ""
                    return R.NAME_NOT_UNIQUE, f"{name!r} is taken in this run.", ""
                stem, n = name or "object", 1
                while f"{stem}_{n}" in taken:
                    n += 1
                name = f"{stem}_{n}"
            obj = obj.model_copy(update={"name": name})
            problem = self._place_problem(obj, live)
            if problem:
                return R.INVALID_POSE, problem, ""
            return Result.RESULT_OK, self._put(edit_event({"spawn": obj.model_dump(
                mode="json", exclude_none=True)}), f"{name!r} is put into the world"), name

    def delete(self, entity: str) -> tuple[int, str]:
        """(result code, message) of a DeleteEntity request."""
        if (answer := self.robots.delete(entity)) is not None:  # a robot a client brought
            return answer
        with self._lock:
            if entity not in self.live():
                if entity == "world" or entity in self.world().names:
                    return (Result.RESULT_OPERATION_FAILED, f"{entity!r} is part of the world "
                            "file (or its robot): only spawned objects can be deleted.")
                return Result.RESULT_NOT_FOUND, f"no spawned object {entity!r} is in the world."
            return Result.RESULT_OK, self._put(edit_event({"delete": entity}),
                                               f"{entity!r} is taken out of the world")

    def _put(self, edit: EventSpec, what: str) -> str:
        self.edits.append(edit)
        boundary = self.control.boundary
        self.arrivals.put(self.topic, String(data=edits_text(self.edits)))
        k = -(-boundary // self.external_period) * self.external_period
        return (f"{what} at tick {k} (the next tick boundary) or, if the run is past it, the "
                "next one.")

    def _place_problem(self, obj: ObjectSpec, live: dict[str, ObjectSpec]) -> str:
        """Why ``obj`` cannot stand where it is asked to (inside an obstacle, a static
        object, the robot where it is now), or ''."""
        now = max(1, tick_time_ns(self.control.boundary, self.scenario.tick_ns))
        events = [edit_event({"spawn": o.model_dump(mode="json", exclude_none=True)})
                  for o in live.values()]
        events = [e.model_copy(update={"at": now}) for e in events]
        new = edit_event({"spawn": obj.model_dump(mode="json", exclude_none=True)})
        problems = [p for p in object_problems([*events, new.model_copy(update={"at": now})],
                                               self.world())
                    if p[0].startswith(f"events[{len(events)}]")]
        if problems:
            return f"{obj.name!r} cannot stand there: {problems[0][1]}"
        if self.robot is not None and obj.footprint_radius is not None:
            state, _ = self.robot.state()
            if state is not None:
                p = state.pose.position
                gap = math.hypot(p.x - obj.pose.x, p.y - obj.pose.y)
                radius = self._robot_radius()
                if gap < radius + obj.footprint_radius:
                    return (f"{obj.name!r} cannot stand there: it would overlap the robot "
                            f"{self.robot.name!r}, at ({p.x:.3g}, {p.y:.3g}) now.")
        return ""

    def _robot_radius(self) -> float:
        from runtime.build import scenario_robots

        robots = scenario_robots(self.scenario)
        return robots[0].footprint_radius if len(robots) == 1 else 0.0


def object_spawner(scenario: Scenario, control: RunControl, arrivals: Arrivals | None,
                   robot=None) -> ObjectSpawner | None:
    """The spawner of a run whose physics node takes clients' world edits through the
    external node (an interactive scenario, live arrivals); None otherwise."""
    if arrivals is None or scenario.world is None:
        return None
    for plan in scenario.nodes.values():
        for inp in plan.inputs:
            if (inp.topic == WORLD_EDITS_TOPIC and inp.producer == EXTERNAL_NAME
                    and inp.graph_topic in arrivals.topics):
                return ObjectSpawner(scenario, control, arrivals, inp.graph_topic, robot)
    return None
