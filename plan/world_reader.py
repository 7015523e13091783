"""What resolving a scenario needs to know of its world files, asked of the wing that loads
them (``descriptions.load.WORLDS``): plan/ itself never loads MuJoCo or USD.

A compiled world is opaque here: plan/ hands it to the node classes' own world checks
(``world_problems``, ``world_warnings``, ``period_problems``) and reads nothing out of it
but the names of its joints (``ScenarioChecks.check_joint_goal``). So are the robot models
(``robot_models``, ``described_robot``): plan/ hands each to its nodes' ``robot_problems``
and ``world_problems`` and reads only its ``name``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

from plan.events import ObjectSpec, RobotEntry, WorldObjects
from plan.model import ScenarioModel
from plan.robots import RobotsLayout


class WorldReader(Protocol):
    """The world loader's side of scenario resolution."""

    def world_model(self, world: Path) -> Any:
        """The compiled world; ``plan.errors.WorldError`` naming what is wrong with it."""

    def robots_layout(self, path: Path, model: ScenarioModel) -> RobotsLayout | None:
        """The ``robots:`` section checked against the world and placed (None without one);
        ``ScenarioError`` naming the key."""

    def entering_robot(self, path: Path, entry: RobotEntry, key: str, base_body: str
                       ) -> tuple[Path, str, str]:
        """A robot an event brings in with its own description: (the description, its
        reader's settings, its root body); ``ScenarioError`` naming ``key`` when it does not
        load."""

    def swarm_model(self, world: Path, layout: RobotsLayout) -> Any:
        """The compiled swarm world: the arena with every robot of ``layout``."""

    def robot_models(self, world: Path, layout: RobotsLayout | None, names: dict[str, Any]
                     ) -> tuple[Any, ...]:
        """The robot models of the world as the run gives them to its nodes, read by the
        description names ``names`` (``StepNode.description_names``, merged); none in a
        world without the robot. ``plan.errors.WorldError`` when the world does not have
        what the names name."""

    def described_robot(self, layout: RobotsLayout, name: str) -> Any | None:
        """Robot ``name`` of ``layout`` as the run gives it to its nodes, where a description
        reader made its model (URDF, xacro, USD: its names are the model's); None for an MJCF
        robot, whose model is read from the world by the names its nodes' parameters give
        (``robot_models``, once those names are checked)."""

    def world_objects(self, world_model: Any, start: tuple[str, float, float] | None
                      ) -> WorldObjects:
        """What a scenario's events are checked against (``plan.events``): the world's
        names, static obstacles, and its robots and loose objects where they start
        (``start``: a body moved to (x, y) by the physics node's start parameter)."""

    def object_problem(self, obj: ObjectSpec) -> str | None:
        """Why a spawned object cannot be made (a mesh file that does not load), or None."""
