"""A scenario with one robot in a ``robots:`` section (a user's robot, URDF or MJCF, doing
nav's task) gets nav's report, not the swarm's: its topics are at the root (or under the
namespace its entry names), its goal is the robot's (``orchestrator.outputs.picture`` draws
it)."""

from __future__ import annotations

from types import SimpleNamespace

from plan.robots import namespace_in, namespaced


def lone_robot(scenario) -> str | None:
    """The name of the only robot of the scenario's ``robots:`` section; None without one
    (nav's own layout) or with several (a swarm)."""
    layout = getattr(scenario, "robots", None)
    if layout is None or len(layout.robots) != 1:
        return None
    return layout.robots[0].name


def topics_of(scenario, topics: tuple[str, ...]) -> dict[str, str]:
    """Each of nav's ``topics`` -> the topic the run has it on (under its lone robot's
    namespace, if it has one)."""
    robot = lone_robot(scenario)
    namespace = namespace_in(scenario.robots, robot)
    return {t: namespaced(namespace, t) for t in topics}


def robot_goal(scenario):
    """The lone robot's goal as the scenario's ``goal:`` gives nav's (x, y, yaw and the
    tolerances as attributes); None without a lone robot."""
    robot = lone_robot(scenario)
    return None if robot is None else SimpleNamespace(**scenario.robots.goal_of(robot))
