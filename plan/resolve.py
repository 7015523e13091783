"""Resolve a validated scenario model into a ``Scenario``: checks, classes, parameters,
world, the robot's model, tick, topics and schedule, in the order their errors are
reported; every independent problem in one error."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from plan.checks import ScenarioChecks
from plan.errors import Problems, ScenarioNotice
from plan.events import (
    RobotEntry,
    RobotPose,
    object_problems,
    physics_period,
    robot_windows,
    timing_problems,
)
from plan.external_node import complete_model
from plan.hardware_wiring import (
    check_manager_rate,
    fold_managers,
    hand_wiring_notices,
    with_robot_managers,
)
from plan.kinds import catalogue
from plan.model import ScenarioModel
from plan.robots import (
    BY_CLIENT,
    RobotPlacement,
    RobotsLayout,
    namespace_in,
    namespaced,
    per_robot,
    robot_namespaces,
    robot_of,
)
from plan.roles import role_of
from plan.scenario import NodePlan, Scenario
from plan.schedule import NEVER, Edge, Schedule, Window
from plan.spawnables import spawnable_problems
from plan.templates import expand_nodes
from plan.timeutil import tick_at_ns
from plan.topics import node_inputs, node_outputs, producers
from plan.world_reader import WorldReader


def resolve(path: Path, model: ScenarioModel, sha: str, overrides: dict, worlds: WorldReader
            ) -> Scenario:
    """The runnable scenario of a schema-valid model read from ``path``, its world files
    read through ``worlds``; one ScenarioError naming every problem found: each check runs
    when what it reads is right, whatever the others found."""
    found = Problems()
    with found.collecting():
        scenario = _resolve(path, model, sha, overrides, worlds, found)
    found.raise_any()
    return scenario


def _resolve(path: Path, model: ScenarioModel, sha: str, overrides: dict, worlds: WorldReader,
             found: Problems) -> Scenario:
    """``resolve``'s stages; what a stage finds is kept in ``found``, and a stage that
    needs an earlier one right raises what was found."""
    ScenarioChecks(path, model).check_finite("", model.model_dump(by_alias=True,
                                                                  exclude={"nodes"}))
    layout = worlds.robots_layout(path, model)  # many robots: placed, and templates expanded
    section_robots = frozenset(layout.names) if layout is not None else frozenset()
    layout = entering_robots(path, model, layout, worlds)  # events' robots: planned now
    layout = client_robots(path, model, layout, worlds)  # and those clients may bring in
    model = read_settings_out(model)
    hand_wired = hand_wiring_notices(path, model)
    model, one_line, told = with_robot_managers(path, model, *tagged_controllers(layout, worlds))
    hand_wired += told
    model, origins = expand_nodes(path, model, layout)
    model = complete_model(path, model)
    model = with_event_files(path, model, found, worlds)
    for key, problem, accepted in spawnable_problems(path.parent, model.spawnables):
        found.add(ScenarioChecks(path, model).fail(key, problem, accepted))
    where = ScenarioChecks(path, model, origins, worlds, found)
    classes, params = {}, {}
    for i, spec in enumerate(model.nodes):
        with found.collecting():
            classes[i] = where.node_class(i, spec)
            params[i] = where.node_params(i, spec, classes[i][1])
            where.check_finite(where.node_key(i, "params"), params[i].model_dump())
    with found.collecting():  # before the world's timestep against physics' period
        check_manager_rate(path, model, params, origins, one_line)
    needs_world = any(cls.needs_world for _, cls in classes.values())
    world = world_model = None
    with found.collecting():
        world, world_model = where.world_path(needs_world and layout is None)
        if needs_world and layout is not None:  # the arena was checked by robots_layout
            world_model = worlds.swarm_model(world, layout)
    world_warnings = []
    if world_model is not None:
        fit = {i: classes[i] for i in params}  # the nodes whose class and params are right
        before = len(found.errors)
        world_warnings = where.check_world_fit(fit, params, world_model, layout)
        if len(found.errors) == before and len(params) == len(model.nodes):
            with found.collecting():  # the robot model is read by the names checked above
                where.check_robot_needs(classes, params, world, layout, world_model)
    tick_ns = last_tick = None
    with found.collecting():
        tick_ns = where.tick_ns()
        last_tick = where.last_tick(tick_ns)
    if len(params) < len(model.nodes):
        found.raise_any()  # the topics of a node whose class or params are wrong are unknown
    # a controller manager is folded into physics only when all is right so far; otherwise
    # the checks go on without the fold, so that independent mistakes are reported together
    folded = None
    if not found.errors:
        model, folded = fold_managers(path, model, params, origins, one_line)
    if folded is not None:  # the node list changed: its classes and parameters again
        hand_wired += folded
        where = ScenarioChecks(path, model, origins, worlds, found)
        classes = {i: where.node_class(i, spec) for i, spec in enumerate(model.nodes)}
        params = {i: where.node_params(i, spec, classes[i][1])
                  for i, spec in enumerate(model.nodes)}
    outputs = {}
    for i, spec in enumerate(model.nodes):
        with found.collecting():
            outputs[i] = node_outputs(where, i, spec, classes[i][1], params[i])
    if len(outputs) < len(model.nodes):
        found.raise_any()  # an input's publisher may be the node whose outputs are wrong
    publishers = producers(where, outputs, {i: cls for i, (_, cls) in classes.items()})
    check_events(where, model, outputs, world_model, params, section_robots)
    inputs = {i: node_inputs(where, i, spec, classes[i][1], params[i], publishers)
              for i, spec in enumerate(model.nodes)}
    found.raise_any()  # what follows reads every node's inputs, the tick and the world
    nodes: dict[str, NodePlan] = {}
    edges = [Edge(spec.name, inp.producer, inp.graph_topic, inp.mode)
             for i, spec in enumerate(model.nodes) for inp in inputs[i]]
    taken = {edge.topic for edge in edges}
    for i, spec in enumerate(model.nodes):
        nodes[spec.name] = NodePlan(
            name=spec.name, spec=spec, class_ref=classes[i][0], params=params[i],
            period_ticks=spec.period_ns // tick_ns, outputs=outputs[i][0],
            output_names=outputs[i][1], inputs=inputs[i], latched=outputs[i][2],
            role=role_of(spec, classes[i][0], getattr(params[i], "gate", "auto"),
                         catalogue().external),
            output_periods=own_periods(where, spec, classes[i][1], params[i], tick_ns),
            unconsumed=frozenset(own for own, graph in outputs[i][1].items()
                                 if graph not in taken))
    with found.collecting():
        where.check_cycles(edges)
    with found.collecting():
        where.check_foreign_counts(nodes, edges)
    with found.collecting():
        where.check_twin(nodes)
    found.raise_any()  # a schedule has no cycle
    windows, topic_windows = robot_windows_of(layout, nodes, tick_ns)
    for name in windows:
        if nodes[name].role.is_foreign:
            raise where.fail(f"nodes[{origins.get(name, 0)}] ({name.partition('@')[0]})"
                             ".for_each", f"{name} is a foreign program of a robot that "
                             "enters or leaves the run; foreign programs cannot be dormant "
                             "yet.", "a cosim node kind for robots that enter, or "
                             "robots: [the robots there from the start] on this template.")
    if topic_windows:
        nodes = {name: _with_windows(plan, topic_windows, windows) for name, plan in
                 nodes.items()}
    topic_periods = {p.output_names[own]: ticks for p in nodes.values()
                     for own, ticks in p.output_periods.items()}
    input_periods = {}
    for i, spec in enumerate(model.nodes):
        periods = own_periods(where, spec, classes[i][1], params[i], tick_ns, "input_periods")
        input_periods.update({(spec.name, inp.graph_topic): periods[inp.topic]
                              for inp in inputs[i] if inp.topic in periods})
    schedule = Schedule(tick_ns, last_tick, {n: p.period_ticks for n, p in nodes.items()},
                        edges, windows, topic_windows, topic_periods, input_periods)
    warnings = hand_wired + world_warnings + unconsumed_remaps(path, nodes, edges, layout)
    return Scenario(path, model, tick_ns, nodes, schedule, world, sha, overrides, warnings,
                    layout)


def own_periods(where: ScenarioChecks, spec, cls, params, tick_ns,
                hook: str = "output_periods") -> dict[str, int]:
    """The node's outputs (``hook`` 'input_periods': inputs) that have a period of their
    own, a whole multiple of the node's (own name -> ticks): those the node class's
    ``output_periods(params)`` (``input_periods``) names (the controllers' topics of a
    manager run in the physics step below physics' rate), each robot's under its
    namespace."""
    periods = getattr(cls, hook, None)
    if periods is None:
        return {}
    own = per_robot(periods(params), robot_namespaces(where.model.robots, spec.robots)) or {}
    node = spec.period_ns // tick_ns
    ticks = {topic: int(period / tick_ns) for topic, period in own.items()}
    return {topic: t for topic, t in ticks.items() if t != node}


def tagged_controllers(layout: RobotsLayout | None, worlds: WorldReader
                       ) -> tuple[str, tuple[str, ...]]:
    """(the robots: section's description, the controllers files the ``<parameters>`` of
    its ros2_control plugin tag name: gz_ros2_control's ``<gazebo><plugin>``); ('', ())
    without a robots: section or a described robot."""
    if layout is None or not layout.names:
        return "", ()
    robot = worlds.described_robot(layout, layout.names[0])
    files = tuple(getattr(robot, "controllers_files", ()))
    return (str(layout.description), files) if files else ("", ())


def entering_robots(path: Path, model: ScenarioModel, layout: RobotsLayout | None,
                    worlds: WorldReader | None = None) -> RobotsLayout | None:
    """The layout with each robot an event brings in (``events: - robot:``), entering and
    leaving at its events' times: its ``for_each: robot`` nodes are planned like the
    others' (plan/robots.py). A robot event needs a robots: section (its description)."""
    entering = robot_windows(list(model.events))
    if not entering:
        return layout
    if layout is None:
        i = next(i for i, e in enumerate(model.events) if e.robot is not None)
        raise ScenarioChecks(path, model).fail(
            f"events[{i}] ({model.events[i].name}).robot", "a robot that enters needs the "
            "robots: section's description, and the scenario has no robots: section.",
            "a robots: section (description and the robots there from the start).")
    added = []
    for event in model.events:
        if event.robot is None or event.robot.name in layout.names + [a.name for a in added]:
            continue  # a name taken: said by the event checks
        r = event.robot
        enter, leave = entering[r.name]
        own = {}
        if r.description is not None and worlds is not None:  # its own description
            i = model.events.index(event)
            description, settings, base = worlds.entering_robot(
                path, r, f"events[{i}] ({r.name}).robot", layout.base_body)
            own = {"description": description, "settings": settings, "base_body": base}
        added.append(RobotPlacement(r.name, (r.start.x, r.start.y, r.start.yaw),
                                    (r.goal.x, r.goal.y, r.goal.yaw), enter, leave, **own))
    return dataclasses.replace(layout, robots=layout.robots + tuple(added))


def client_robots(path: Path, model: ScenarioModel, layout: RobotsLayout | None,
                  worlds: WorldReader) -> RobotsLayout | None:
    """The layout with each robot a client may bring in (``spawnables[].robots``): planned
    like an event's robot, its window not opened until a SpawnEntity takes it."""
    slots = [(i, j, entry, slot) for i, entry in enumerate(model.spawnables)
             for j, slot in enumerate(entry.robots)]
    if not slots:
        return layout
    where = ScenarioChecks(path, model)
    if layout is None:
        raise where.fail("spawnables[0].robots", "a robot that enters needs the robots: "
                         "section, and the scenario has none.", "a robots: section.")
    if not model.interactive:
        raise where.fail("interactive", "clients bring robots in (spawnables[].robots) only "
                         "in an interactive scenario.", "interactive: true.")
    added = []
    for i, j, entry, slot in slots:
        key = f"spawnables[{i}].robots[{j}]"
        if slot.name in layout.names + [a.name for a in added]:
            raise where.fail(f"{key}.name", f"{slot.name!r} is already a robot's name.",
                             "a name of its own.")
        robot = RobotEntry(name=slot.name, start=RobotPose(x=0.0, y=0.0), goal=slot.goal,
                           description=entry.path, urdf=entry.urdf, usd=entry.usd)
        description, settings, base = worlds.entering_robot(path, robot, f"spawnables[{i}]",
                                                            layout.base_body)
        added.append(RobotPlacement(slot.name, (0.0, 0.0, 0.0), (slot.goal.x, slot.goal.y,
                                    slot.goal.yaw), BY_CLIENT, None, description, settings,
                                    base))
    return dataclasses.replace(layout, robots=layout.robots + tuple(added))


def read_settings_out(model: ScenarioModel) -> ScenarioModel:
    """The model with each robot event's reader settings (urdf:, usd:) left out: the layout
    holds them, read (``RobotPlacement.settings``), and an event must be hashable (nodes
    key their cached worlds by the events)."""
    if not any(e.robot is not None and (e.robot.urdf or e.robot.usd) for e in model.events):
        return model
    events = [e if e.robot is None else e.model_copy(update={"robot": e.robot.model_copy(
        update={"urdf": None, "usd": None})}) for e in model.events]
    return model.model_copy(update={"events": events})


def robot_windows_of(layout: RobotsLayout | None, nodes: dict[str, NodePlan], tick_ns
                     ) -> tuple[dict[str, Window], dict[str, Window]]:
    """The ticks each robot that enters or leaves is in the world: its nodes' windows
    (NAME@ROBOT) and its topics' (every output under /ROBOT/), ``plan.schedule``."""
    if layout is None:
        return {}, {}
    robots = {r.name: (NEVER if r.enter_ns == BY_CLIENT else tick_at_ns(r.enter_ns, tick_ns),
                       None if r.leave_ns is None else tick_at_ns(r.leave_ns, tick_ns))
              for r in layout.robots if r.enter_ns or r.leave_ns is not None}
    if not robots:
        return {}, {}
    windows = {name: robots[robot_of(name)] for name in nodes if robot_of(name) in robots}
    topic_windows = {}
    for plan in nodes.values():
        for graph in plan.outputs:
            robot = graph.split("/")[1] if graph.count("/") >= 2 else None
            if robot in robots:
                topic_windows[graph] = robots[robot]
    return windows, topic_windows


def _with_windows(plan: NodePlan, topic_windows: dict[str, Window],
                  windows: dict[str, Window]) -> NodePlan:
    """A node that publishes a robot's topics, not being the robot's own (the world node):
    each such output's window, so that it publishes them only while the robot is there."""
    if plan.name in windows:
        return plan
    own = {own: topic_windows[graph] for own, graph in plan.output_names.items()
           if graph in topic_windows}
    if not own:
        return plan
    relatch = {w[0] for w in topic_windows.values() if 0 < w[0] < NEVER} if plan.latched \
        else set()  # its fixed frames (/tf_static) again with each robot that enters
    return dataclasses.replace(plan, windows=own, relatch=relatch)


def with_event_files(path: Path, model: ScenarioModel, found: Problems, worlds: WorldReader
                     ) -> ScenarioModel:
    """The model with each spawned mesh's file made absolute (every node reads it from its
    own working directory); a file that does not exist or does not load is a problem naming
    the key."""
    events = list(model.events)
    for i, event in enumerate(events):
        obj = event.spawn
        if obj is None or obj.mesh is None:
            continue
        file = (path.parent / obj.mesh).resolve()
        if not file.is_file():
            found.add(ScenarioChecks(path, model).fail(
                f"events[{i}] ({obj.name}).spawn.mesh", f"mesh file {obj.mesh!r} does not "
                f"exist ({file}).", "the path of an STL or OBJ file, relative to this file."))
            continue
        obj = obj.model_copy(update={"mesh": str(file)})
        problem = worlds.object_problem(obj)
        if problem:
            found.add(ScenarioChecks(path, model).fail(
                f"events[{i}] ({obj.name}).spawn.mesh", f"mesh file {obj.mesh!r} does not "
                f"load: {problem}", "an STL or OBJ file MuJoCo reads."))
            continue
        events[i] = event.model_copy(update={"spawn": obj})
    return model.model_copy(update={"events": events}) if model.events else model


def check_events(where: ScenarioChecks, model: ScenarioModel, outputs: dict, world_model,
                 params: dict, robots: frozenset[str] = frozenset()) -> None:
    """The events' times against the physics node's ticks and the duration, and their names
    and places against the world (``plan.events``); problems kept in ``where.found``."""
    if not model.events:
        return
    period = physics_period({spec.name: outputs[i][0] for i, spec in enumerate(model.nodes)},
                            {spec.name: spec.period_ns for spec in model.nodes})
    problems = timing_problems(model.events, period, model.duration)
    if world_model is not None and where.worlds is not None:
        start = next(((p.base_body, p.start.x, p.start.y) for p in params.values()
                      if getattr(p, "start", None) is not None
                      and isinstance(getattr(p, "base_body", None), str)), None)
        objects = where.worlds.world_objects(world_model, start)
        objects = dataclasses.replace(objects, robots=robots)  # the robots: section's
        problems += object_problems(model.events, objects)
    for key, problem, accepted in problems:
        where.found.add(where.fail(key, problem, accepted))


def unconsumed_remaps(path: Path, nodes: dict[str, NodePlan], edges: list[Edge],
                      layout: RobotsLayout | None = None) -> list[str]:
    """Warnings for outputs remapped to a name no node consumes (allowed: ROS tools see it);
    a template's own topics in its robot's namespace are no remap of the scenario's."""
    consumed = {e.topic for e in edges}
    return [ScenarioNotice(path, f"nodes ({plan.name}).remap.{own}", f"{graph} is published "
                          "but no node of the scenario consumes it (only ROS tools will see "
                          "it).", "a remap to a topic a node of the scenario consumes.")
            for plan in nodes.values() for own, graph in plan.output_names.items()
            if own != graph and graph not in consumed
            and graph != namespaced(namespace_in(layout, robot_of(plan.name)), own)]
