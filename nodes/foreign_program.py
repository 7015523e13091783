"""Foreign nodes: ordinary ROS 2 programs that know nothing of cosim, run in lockstep.

A scenario names the program's ``command``, its inputs, and in ``params`` the type of each
output and, where it wants that checked, how many messages it publishes on it per
activation. The orchestrator starts it (with ``use_sim_time``), feeds it its inputs, learns
from its gate's acknowledgement that it has finished a tick and how many messages that tick
published (an ungated program: by counting them against the declared count, default 1),
and hashes what it published. The run stays deterministic as long as the program is a
deterministic function of its inputs.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from nodes.contract import StepNode, Tick
from plan.ros_types import message_class


def installed_types(topics: dict[str, str]) -> dict[str, str]:
    """``topics`` (topic -> message type name) unchanged, once every type is installed."""
    for type_name in topics.values():
        message_class(type_name)
    return topics


class ForeignParams(BaseModel):
    """What cosim needs to know of a foreign program: its outputs and their message counts."""

    model_config = ConfigDict(extra="forbid")
    outputs: dict[str, str] = Field(min_length=1, description="topic -> message type, e.g. "
                                    "{/cmd_vel: geometry_msgs/msg/Twist}")
    per_activation: dict[str, int] = Field(default_factory=dict, description="topic -> "
                                           "the exact number of messages per activation, "
                                           "checked at every tick (a gated program: any "
                                           "number where not declared; an ungated one: 1)")
    silent_at_start: bool = Field(False, description="true: the program publishes nothing "
                                  "at tick 0 (checked for a gated program; needed for an "
                                  "ungated one, whose outputs then no node may consume)")

    gate: Literal["auto", "python", "rmw"] = Field(
        "auto", description="what makes its executor take each tick whole: 'python' (cosim's "
        "rclpy gate), 'rmw' (cosim's RMW implementation, any language on rcl), or 'auto': "
        "python for a Python program, rmw for any other. A program is gated when its gate "
        "serves it (rmw: where make install built it), and may then publish any number of "
        "messages per tick")

    _types_exist = field_validator("outputs")(lambda cls, value: installed_types(value))

    def count(self, topic: str, activation: int = 1) -> int:
        """Messages an ungated program publishes on ``topic`` at its ``activation``-th
        activation (what the orchestrator counts to know the activation is done)."""
        if activation == 0 and self.silent_at_start:
            return 0
        return self.per_activation.get(topic, 1)

    def exact(self, topic: str, activation: int) -> int | None:
        """The count the scenario declares for a gated program's ``activation`` on
        ``topic`` (checked against its gate's acknowledgement), or None: any number."""
        if activation == 0 and self.silent_at_start:
            return 0
        return self.per_activation.get(topic)


class ForeignNode(StepNode):
    """Stands for a foreign program in the scenario graph; it has no step of its own."""

    Params = ForeignParams

    @classmethod
    def outputs(cls, params: ForeignParams) -> dict[str, type]:
        """The declared outputs and their message classes."""
        return {topic: message_class(name) for topic, name in params.outputs.items()}

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """A foreign program only runs as its own process."""
        raise RuntimeError(f"{self.config.name} is a foreign program; it cannot run in-process")
