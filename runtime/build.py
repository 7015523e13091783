"""Build a step node from its entry in the checked plan: the one way every driver (node
process, realtime node, in-process reference, benchmarks) makes and resets a node."""

from __future__ import annotations

from nodes.contract import NodeConfig, StepNode
from nodes.registry import load_class
from plan.options import RunOptions
from plan.robots import robot_of
from plan.scenario import Scenario


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
    return NodeConfig(name=name, params=plan.params, tick_ns=scenario.tick_ns,
                      period_ns=plan.spec.period_ns, world=scenario.world, goal=goal,
                      joint_goal=joint_goal, scenario_dir=scenario.file.parent.resolve(),
                      render_warm_up=warm_up, robots=scenario.robots)


def make_node(scenario: Scenario, name: str, options: RunOptions | None = None) -> StepNode:
    """Instantiate and reset node ``name``'s step class."""
    node = load_class(scenario.nodes[name].class_ref)()
    node.reset(scenario.model.seed, node_config(scenario, name, options))
    return node
