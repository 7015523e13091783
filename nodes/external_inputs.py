"""The node a scenario's ``external:`` section becomes: what enters the run from outside.

Messages from outside the run (a NavigateToPose client, a rosbridge client, a real robot)
arrive whenever they arrive; the orchestrator hands each one to this node as an input of
the first tick not yet started (a tick boundary), and the node publishes, at each of its
activations, the latest message of every topic (a default-constructed one, empty
``header.frame_id`` where it has a header, until the first arrives). Its outputs are
recorded and hashed like any node's, so a run with the same arrivals gives the same digest,
and ``--replay`` feeds the recorded ones back.
"""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field, field_validator

from nodes.contract import StepNode, Tick
from nodes.foreign_program import installed_types
from plan.ros_types import message_class


class ExternalParams(BaseModel):
    """The topics that enter from outside and their message types."""

    model_config = ConfigDict(extra="forbid")
    topics: dict[str, str] = Field(min_length=1)

    _types_exist = field_validator("topics")(lambda cls, value: installed_types(value))


class ExternalInputs(StepNode):
    """Holds the latest message from outside per topic and publishes it every activation."""

    Params = ExternalParams
    runs_in_orchestrator: ClassVar[bool] = True  # no process: the orchestrator steps it
    # it publishes the latest of every topic; a topic of a robot that enters or leaves (a
    # controller manager's requests) goes out only while the robot is in the run
    # (runtime.activation keeps those due)
    holds_outputs: ClassVar[bool] = True

    @classmethod
    def outputs(cls, params: ExternalParams) -> dict[str, type]:
        """Every external topic with its message class."""
        return {topic: message_class(name) for topic, name in params.topics.items()}

    def setup(self) -> None:
        """Nothing has arrived yet: default messages."""
        self.held = {topic: cls() for topic, cls in self.outputs(self.params).items()}
        self.arrived = 0

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """``inputs``: what arrived from outside for this tick (at most one per topic)."""
        for topic, msg in inputs.items():
            self.held[topic] = msg
            self.arrived += 1
        return dict(self.held)

    def metrics(self) -> dict[str, float]:
        """How many messages came in from outside."""
        return {"external_messages": float(self.arrived)}
