"""Build a step node from its entry in the checked plan: the one way every driver (node
process, realtime node, in-process reference, benchmarks) makes and resets a node."""

from __future__ import annotations

from descriptions.robot_model import RobotModel
from descriptions.robot_reader import RobotNames, world_robots
from nodes.contract import NodeConfig, StepNode
from nodes.registry import load_class
from plan.options import RunOptions
from plan.robots import merged_names, robot_of
from plan.scenario import EXTERNAL_NAME, Scenario


def node_config(scenario: Scenario, name: str, options: RunOptions | None = None
                ) -> NodeConfig:
    """The NodeConfig every driver gives node ``name`` at reset."""
    plan = scenario.nodes[name]
    goal = scenario.model.goal.model_dump() if scenario.model.goal else None
    robot = robot_of(name)
    if scenario.robots is not None and robot is not None:
        goal = scenario.robots.goal_of(robot)
    joint_goal = scenario.model.joint_goal.model_dump() if scenario.model.joint_goal else None
    warm_up = (options or RunOptions()).camera_warm_up
    every = robots = scenario_robots(scenario) if load_class(plan.class_ref).needs_world else ()
    if robot is not None:
        robots = tuple(r for r in robots if r.name == robot)
    return NodeConfig(name=name, params=plan.params, tick_ns=scenario.tick_ns,
                      period_ns=plan.spec.period_ns, world=scenario.world, goal=goal,
                      joint_goal=joint_goal, scenario_dir=scenario.file.parent.resolve(),
                      render_warm_up=warm_up, robots=robots,
                      swarm=every if scenario.robots is not None else (), layout=scenario.robots,
                      events=tuple(scenario.model.events),
                      held_inputs=frozenset(inp.topic for inp in plan.inputs
                                            if inp.producer == EXTERNAL_NAME))


def scenario_robots(scenario: Scenario) -> tuple[RobotModel, ...]:
    """Every robot of the scenario's world, read once per process by the names its nodes'
    parameters give (``StepNode.description_names``) or else cosim's conventions; none
    without a world, or in a world without the robot's base body."""
    if scenario.world is None:
        return ()
    held = _ROBOTS.get(id(scenario))  # world_robots' own cache hashes the whole layout
    if held is not None and held[0] is scenario:
        return held[1]
    robots = world_robots(scenario.world, scenario.robots, description_names(scenario))
    if len(_ROBOTS) >= 4:
        _ROBOTS.clear()
    _ROBOTS[id(scenario)] = (scenario, robots)
    return robots


_ROBOTS: dict[int, tuple[Scenario, tuple[RobotModel, ...]]] = {}
"""scenario_robots by scenario (kept with it, so that its id is not reused meanwhile)."""


def description_names(scenario: Scenario) -> RobotNames:
    """The description's names as the scenario's nodes give them; two nodes that name one
    thing differently are a ValueError naming both. Asked by every node that needs the
    world, it is worked out once per scenario (it reads every node: a process of a thousand
    lidars would otherwise read a million)."""
    held = _NAMES.get(id(scenario))
    if held is not None and held[0] is scenario:
        return held[1]
    names = RobotNames.of(merged_names([
        (plan.name, load_class(plan.class_ref).description_names(plan.params))
        for plan in scenario.nodes.values()]))
    if len(_NAMES) >= 4:
        _NAMES.clear()
    _NAMES[id(scenario)] = (scenario, names)
    return names


_NAMES: dict[int, tuple[Scenario, RobotNames]] = {}
"""description_names by scenario (kept with it, so that its id is not reused meanwhile)."""


def make_node(scenario: Scenario, name: str, options: RunOptions | None = None) -> StepNode:
    """Instantiate and reset node ``name``'s step class."""
    node = load_class(scenario.nodes[name].class_ref)()
    node.reset(scenario.model.seed, node_config(scenario, name, options))
    return node
