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
mapping joint -> JointReading, refreshed before every update): the MuJoCo system interface
(``nodes.ros2_control.hosted``) backs it with the joints' readings from MjData
(``JointStates``), a unit test with a plain dict.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass
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


class JointStates(Mapping):
    """A system interface's ``HardwareState``: its joints' positions, velocities and
    efforts as three lists in the hardware's joint order (``positions``, ``velocities``,
    ``efforts``), replaced at every read (``refresh``). A controller that reads every joint
    in that order (a joint state broadcaster) takes the lists; a lookup by joint gets a
    JointReading, made for every joint at the first lookup after a read (the lists of a
    read are never changed, so a reading or list a controller keeps stays what it was)."""

    __slots__ = ("joints", "_known", "positions", "velocities", "efforts", "_readings")

    def __init__(self, joints: list[str]):
        self.joints = tuple(joints)
        self._known = frozenset(self.joints)
        self.refresh([0.0] * len(self.joints), [0.0] * len(self.joints),
                     [0.0] * len(self.joints))

    def refresh(self, positions: list[float], velocities: list[float],
                efforts: list[float]) -> None:
        """The newest readings, each a list in the joints' order (kept, not copied)."""
        self.positions, self.velocities, self.efforts = positions, velocities, efforts
        self._readings: dict[str, JointReading] | None = None

    def _by_joint(self) -> dict[str, JointReading]:
        readings = self._readings
        if readings is None:
            readings = self._readings = {
                name: JointReading(p, v, e) for name, p, v, e in
                zip(self.joints, self.positions, self.velocities, self.efforts, strict=True)}
        return readings

    def __getitem__(self, joint: str) -> JointReading:
        return self._by_joint()[joint]

    def __contains__(self, joint: object) -> bool:
        return joint in self._known

    def __iter__(self):
        return iter(self.joints)

    def __len__(self) -> int:
        return len(self.joints)


class Update:
    """What one update of a controller gives: ``commands`` (``joint/interface`` -> value,
    the command interfaces it claims), ``published`` (topic -> message; ``~/x`` is under the
    controller's name) and ``notes`` (what it refused, for the run's log); each empty when
    not given. No one changes ``commands`` once given: a controller may give the same
    mapping again while its commands hold, and the hardware writes it as it wrote it. (A
    plain class with slots: one or more are made at every update.)"""

    __slots__ = ("commands", "published", "notes")

    def __init__(self, commands: dict[str, float] | None = None,
                 published: dict[str, Any] | None = None, notes: list[str] | None = None):
        self.commands = {} if commands is None else commands
        self.published = {} if published is None else published
        self.notes = [] if notes is None else notes

    def __eq__(self, other: object) -> bool:
        return (type(other) is Update and self.commands == other.commands
                and self.published == other.published and self.notes == other.notes)

    def __repr__(self) -> str:
        return (f"Update(commands={self.commands!r}, published={self.published!r}, "
                f"notes={self.notes!r})")


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
