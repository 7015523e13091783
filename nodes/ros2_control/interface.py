"""The one interface every controller has, shaped like ros2_control's
``controller_interface::ControllerInterfaceBase``.

A controller is a pure object: made from its name and its typed parameters (the type's
``Params``, as generate_parameter_library declares them upstream), it says which command and
state interfaces it claims (``joint/interface`` names), goes through the lifecycle
(unconfigured -> inactive -> active -> inactive -> finalized) by ``configure``, ``activate``,
``deactivate`` and ``finalize``, takes the messages of its subscriptions (``on_message``)
and, while active, is updated at the manager's rate (``update(time_ns, period_ns)``), which
returns its commands and the messages it publishes as plain data. It touches no transport.

The hardware's state reaches a controller as ``HardwareState`` loaned at activation (a
mapping joint -> JointReading, refreshed by the manager before every update): today it is
filled from the physics node's /joint_states; a MuJoCo system interface can later back the
same mapping with MjData without changing a controller.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict

NS_PER_S = 1_000_000_000
INTERFACES = ("position", "velocity", "effort")
"""The joint interfaces cosim's hardware has (command and state)."""


class LifecycleState(enum.Enum):
    """A controller's lifecycle state, as ros2_control's lifecycle nodes name them."""

    UNCONFIGURED = "unconfigured"
    INACTIVE = "inactive"
    ACTIVE = "active"
    FINALIZED = "finalized"


class LifecycleError(RuntimeError):
    """A transition that the controller's state does not allow."""


@dataclass
class JointReading:
    """One joint of the hardware's state: position, velocity, effort."""

    position: float
    velocity: float = 0.0
    effort: float = 0.0


HardwareState = Mapping[str, JointReading]
"""joint -> its reading, in the hardware's joint order."""


@dataclass
class Update:
    """What one update of a controller gives: ``commands`` (``joint/interface`` -> value,
    the command interfaces it claims), ``published`` (topic -> message; ``~/x`` is under the
    controller's name) and ``notes`` (what it refused, for the run's log)."""

    commands: dict[str, float] = field(default_factory=dict)
    published: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


class ControllerParams(BaseModel):
    """The base of every controller type's parameters: parameters a controller does not
    declare (``use_sim_time`` from a ``/**`` block, ...) are left alone, as a ROS node
    leaves undeclared overrides."""

    model_config = ConfigDict(extra="ignore", frozen=True)


@dataclass(frozen=True)
class Claim:
    """The interfaces a controller claims: command interfaces it writes, state interfaces it
    reads (``joint/interface`` names)."""

    command: tuple[str, ...] = ()
    state: tuple[str, ...] = ()
    every_state: bool = False  # ``state`` is upstream's ALL: the joints' interfaces the
    # hardware has (a joint_state_broadcaster's); one the hardware lacks is no problem


class ControllerInterface:
    """The base of every controller type (upstream's ControllerInterfaceBase).

    A type sets ``Params`` (its parameter model) and overrides what it uses of:
    ``claim`` (its interfaces), ``publications`` / ``subscriptions`` (its topics, ``~/x``
    under its name, ``/x`` absolute), ``actions`` (the action servers the manager's face
    serves for it), ``notes`` (parameters it reads but does not act on), ``on_configure``,
    ``on_activate``, ``on_deactivate``, ``on_message``, ``update`` and ``metrics``.
    ``drives_base``: its command interfaces are a mobile base's wheels, which cosim's
    hardware realises through the physics node's drive.
    """

    Params: ClassVar[type[ControllerParams]] = ControllerParams
    drives_base: ClassVar[bool] = False
    namespace: str = ""  # its node's ROS namespace ('' the root), set before it is configured

    def __init__(self, name: str, params: ControllerParams):
        self.name = name
        self.params = params
        self.lifecycle = LifecycleState.UNCONFIGURED
        self.state: HardwareState = {}

    # -- what it declares, from its parameters --------------------------------------------

    def claim(self) -> Claim:
        """The command and state interfaces it claims while active."""
        return Claim()

    def publications(self) -> dict[str, type]:
        """topic -> message type of what it publishes while active."""
        return {}

    def subscriptions(self) -> dict[str, type]:
        """topic -> message type of what it takes (``on_message``)."""
        return {}

    def empty_message(self, topic: str) -> Any:
        """What ``topic`` of its publications carries while it is inactive (lockstep wants
        a message on every declared topic at every activation): an empty message of its
        type."""
        return self.publications()[topic]()

    def actions(self) -> dict[str, type]:
        """action name (``~/x``) -> action type of the servers it offers."""
        return {}

    def notes(self) -> list[str]:
        """Parameters it reads but does not act on, said once at load."""
        return []

    def metrics(self) -> dict[str, float]:
        """Numbers the manager's face answers from (``<metric>:<name>`` in the run)."""
        return {}

    # -- the lifecycle ---------------------------------------------------------------------

    def configure(self) -> None:
        """unconfigured (or inactive) -> inactive."""
        if self.lifecycle not in (LifecycleState.UNCONFIGURED, LifecycleState.INACTIVE):
            raise LifecycleError(f"{self.name} cannot be configured while "
                                 f"{self.lifecycle.value}")
        self.on_configure()
        self.lifecycle = LifecycleState.INACTIVE

    def activate(self, state: HardwareState) -> Update:
        """inactive -> active, with the hardware's state loaned; what it commands at once."""
        if self.lifecycle is not LifecycleState.INACTIVE:
            raise LifecycleError(f"{self.name} cannot be activated while "
                                 f"{self.lifecycle.value}")
        self.state = state
        self.lifecycle = LifecycleState.ACTIVE
        return self.on_activate()

    def deactivate(self) -> Update:
        """active -> inactive; the commands it leaves (a halt), then it claims nothing."""
        if self.lifecycle is not LifecycleState.ACTIVE:
            raise LifecycleError(f"{self.name} cannot be deactivated while "
                                 f"{self.lifecycle.value}")
        out = self.on_deactivate()
        self.lifecycle = LifecycleState.INACTIVE
        return out

    def finalize(self) -> None:
        """-> finalized (unloaded)."""
        if self.lifecycle is LifecycleState.ACTIVE:
            self.deactivate()
        self.lifecycle = LifecycleState.FINALIZED

    @property
    def active(self) -> bool:
        """Whether it is active."""
        return self.lifecycle is LifecycleState.ACTIVE

    def on_configure(self) -> None:
        """Make its state from its parameters (at load and on reconfigure)."""

    def on_activate(self) -> Update:
        """Start from the hardware's state (``self.state``)."""
        return Update()

    def on_deactivate(self) -> Update:
        """Stop; the commands left at the hardware."""
        return Update()

    def on_message(self, topic: str, msg: Any, time_ns: int) -> list[str]:
        """A message on one of its subscriptions (given at every update where one is there,
        before ``update``); the notes of what it refused."""
        return []

    def update(self, time_ns: int, period_ns: int) -> Update:
        """One update at ``time_ns``, ``period_ns`` after the last (an active controller)."""
        return Update()


class Fresh:
    """Tells a message that is news from the one an input holds: the external node
    publishes the latest message from outside at every activation, so one equal (by
    ``key``) to the last taken is held, not taken again."""

    def __init__(self):
        self.last: dict[str, Any] = {}

    def __call__(self, topic: str, key: Any) -> bool:
        """Whether ``key`` on ``topic`` differs from the last one seen there."""
        if self.last.get(topic) == key:
            return False
        self.last[topic] = key
        return True


def seconds(period_ns) -> float:
    """A period (int or Fraction of ns) in seconds."""
    return float(period_ns / NS_PER_S)
