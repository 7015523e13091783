"""forward_command_controller/ForwardCommandController: the latest ``~/commands``
(std_msgs/Float64MultiArray, one value per joint in order) goes to its joints' command
interface (``interface_name``); a message of another length, or with a value that is not
finite, is refused (a note) and the last one kept. The joint group controllers
(position_controllers, velocity_controllers, effort_controllers) are this controller with
the interface fixed (``JointGroupController``)."""

from __future__ import annotations

import math
from typing import Any, ClassVar, Literal

from pydantic import Field
from std_msgs.msg import Float64MultiArray

from nodes.ros2_control.interface import Claim, ControllerInterface, ControllerParams, Update
from nodes.ros2_control.param_types import JointNames

COMMANDS = "~/commands"


class JointGroupParams(ControllerParams):
    """A joint group controller's parameters: its joints."""

    joints: JointNames


class ForwardCommandParams(JointGroupParams):
    """forward_command_controller's parameters: its joints and their command interface."""

    interface_name: Literal["position", "velocity", "effort"] = Field(
        description="the command interface of the joints: position, velocity or effort")


class ForwardCommandController(ControllerInterface):
    """Forwards ``~/commands`` to its joints' command interfaces."""

    Params = ForwardCommandParams

    def __init__(self, name: str, params: JointGroupParams):
        super().__init__(name, params)
        self.command: list[float] | None = None

    @property
    def interface(self) -> str:
        """The command interface its joints take."""
        return self.params.interface_name

    def claim(self) -> Claim:
        """``joint/<interface>`` of each joint; no state."""
        return Claim(command=tuple(f"{j}/{self.interface}" for j in self.params.joints))

    def subscriptions(self) -> dict[str, type]:
        """``~/commands``."""
        return {COMMANDS: Float64MultiArray}

    def on_activate(self) -> Update:
        """Nothing commanded until a command comes."""
        self.command = None
        self.keys = [f"{j}/{self.interface}" for j in self.params.joints]
        return Update()

    def on_message(self, topic: str, msg: Any, time_ns: int) -> list[str]:
        """Take a command; the reason it is refused, if it is."""
        values = list(msg.data)
        if not values and not msg.layout.dim:
            return []  # the external node's stand-in until a client sends: nothing was sent
        joints = self.params.joints
        if len(values) != len(joints):
            return [f"{self.name}/commands refused: {len(values)} values for {len(joints)} "
                    f"joints {list(joints)}"]
        if not all(math.isfinite(v) for v in values):
            return [f"{self.name}/commands refused: a value is not finite"]
        self.command = [float(v) for v in values]
        self.commands = dict(zip(self.keys, self.command, strict=True))
        return []

    def update(self, time_ns: int, period_ns: int) -> Update:
        """The latest command (nothing before the first; the same mapping until the next,
        which no one changes)."""
        if self.command is None:
            return Update()
        return Update(commands=self.commands)


class JointGroupController(ForwardCommandController):
    """A forward command controller whose interface its type fixes."""

    Params = JointGroupParams
    fixed_interface: ClassVar[str] = "position"

    @property
    def interface(self) -> str:
        """The command interface its type fixes."""
        return self.fixed_interface
