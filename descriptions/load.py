"""Load a scenario file with its world: ``plan.load.read_scenario`` (pure: YAML, schema,
checks, schedule) with the world files read by this wing (MJCF and USD through MuJoCo).

Everything that can be wrong with a scenario, its world and robots included, is found
before any process starts and reported as a ``ScenarioError`` naming the file and key.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import mujoco

from descriptions.robot_layout import entering_robot, robots_layout
from descriptions.robot_model import RobotModel
from descriptions.robot_reader import RobotNames, described_robot, world_robots
from descriptions.swarm_world import swarm_model
from descriptions.world_edits import object_problem, world_objects
from descriptions.worldfile import check_world
from plan.errors import WorldError
from plan.events import ObjectSpec, RobotEntry, WorldObjects
from plan.load import read_scenario
from plan.model import ScenarioModel
from plan.robots import RobotsLayout
from plan.scenario import Scenario


class MujocoWorlds:
    """The world loader's side of scenario resolution (``plan.world_reader.WorldReader``)."""

    def world_model(self, world: Path) -> mujoco.MjModel:
        """The compiled world; WorldError naming what is wrong."""
        return check_world(world)

    def robots_layout(self, path: Path, model: ScenarioModel) -> RobotsLayout | None:
        """The robots: section checked against the world and placed."""
        return robots_layout(path, model)

    def entering_robot(self, path: Path, entry: RobotEntry, key: str, base_body: str
                       ) -> tuple[Path, str, str]:
        """A robot with its own description, read (``robot_layout.entering_robot``)."""
        return entering_robot(path, entry, key, base_body)

    def swarm_model(self, world: Path, layout: RobotsLayout) -> mujoco.MjModel:
        """The arena with every robot of the layout."""
        return swarm_model(world, layout)

    def robot_models(self, world: Path, layout: RobotsLayout | None, names: dict[str, Any]
                     ) -> tuple[RobotModel, ...]:
        """The robots as the run reads them (``runtime.build.scenario_robots``: the same
        call, cached per process); WorldError naming what the world lacks."""
        robot_names = RobotNames.of(names)
        try:
            return world_robots(world, layout, robot_names)
        except ValueError as exc:
            raise WorldError(world, str(exc)) from None

    def described_robot(self, layout: RobotsLayout, name: str) -> RobotModel | None:
        """Robot ``name``'s model where a description reader made it, else None
        (``robot_reader.described_robot``)."""
        return described_robot(layout, name)

    def world_objects(self, world_model: mujoco.MjModel, start: tuple[str, float, float] | None
                      ) -> WorldObjects:
        """The world's names, obstacles and movers, for the events' checks."""
        return world_objects(world_model, start)

    def object_problem(self, obj: ObjectSpec) -> str | None:
        """Why MuJoCo cannot make a spawned object (its mesh), or None."""
        return object_problem(obj)


WORLDS = MujocoWorlds()


def load_scenario(path: str | Path, overrides: dict[str, Any] | None = None) -> Scenario:
    """Read, check and resolve a scenario file with its world; raise ScenarioError on
    anything wrong.

    ``overrides`` maps dotted keys ('seed', 'nodes.<node name>.rate') to values that replace
    the file's before anything is checked; an error in an overridden value says so.
    """
    return read_scenario(path, WORLDS, overrides)
