"""What clients may spawn: a scenario's ``spawnables:`` list of files and folders, which
GetSpawnables lists (orchestrator/ros_surface/spawnables.py); each path is checked to exist
when the scenario loads."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field

from plan.description_spec import UrdfSpec, UsdSpec
from plan.events import EventName, RobotPose


def _spawnable(value: object) -> object:
    return {"path": value} if isinstance(value, str) else value


class SlotSpec(BaseModel):
    """A robot a client may bring in (SpawnEntity) from a spawnable robot description: its
    name (namespace) and goal; where it starts is the request's initial_pose."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: EventName = Field(description="letters, digits and _; its namespace")
    goal: RobotPose = Field(description="where its controller drives it")


class SpawnableSpec(BaseModel):
    """A file (or a folder of files) a client may spawn from: a robot description (URDF,
    xacro, MJCF, USD), an SDFormat model or a mesh; GetSpawnables lists them. A robot
    description lists the ``robots`` clients may bring in from it: each is planned, its
    ``for_each: robot`` nodes started at launch and dormant until a SpawnEntity of the file
    takes it (the next one not taken)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    path: str = Field(description="a file or folder, relative to the scenario file; a folder "
                      "lists its robot descriptions, SDFormat models and meshes")
    description: str = Field("", description="what it is, for people, e.g. 'a box 30 cm wide'")
    robots: list[SlotSpec] = Field(default_factory=list, description="a robot description: "
                                   "the robots clients may bring in from it, each {name, "
                                   "goal} (the capacity: one SpawnEntity takes one)")
    urdf: UrdfSpec | None = Field(None, description="with robots: how the URDF or xacro is "
                                  "read, as robots.urdf")
    usd: UsdSpec | None = Field(None, description="with robots: how the USD is read, as "
                                "robots.usd")


Spawnable = Annotated[SpawnableSpec, BeforeValidator(_spawnable)]


def spawnable_problems(folder: Path, spawnables: list[SpawnableSpec]
                       ) -> list[tuple[str, str, str]]:
    """Each spawnable's path exists (relative to the scenario's ``folder``): (key, problem,
    accepted) for each that does not."""
    return [(f"spawnables[{i}].path", f"{entry.path!r} does not exist (looked for "
             f"{(folder / entry.path).resolve()}).", "a file or folder relative to the "
             "scenario file.")
            for i, entry in enumerate(spawnables) if not (folder / entry.path).exists()]
