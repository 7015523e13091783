"""The node contract: a node's logic is a pure step function over ROS 2 message objects.

A step node never reads a clock, never sleeps and never touches a transport. It draws
every random number from ``self.rng``, seeded from the scenario seed and the node name.
The runtime (``runtime.lockstep``) or the in-process driver calls it.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict

from descriptions.robot_model import RobotModel
from plan.events import EventSpec
from plan.robots import RobotsLayout
from plan.timeutil import Ns

_MARKED: dict[int, tuple[Any, bytes | None, bool]] = {}  # id -> (a message marked since
# the runtime last took the marks, its bytes past the stamp or None, whether it may be left
# out): the message itself is held, so that an id cannot be reused while it is marked


def constant_message(msg: Any) -> Any:
    """Mark ``msg``, an output of the step now running that it gives again, the same
    object, at many activations (an inactive controller's empty message, a plan until the
    next replan), as never changed again but for its header's stamp, which the runtime
    sets: the runtime may then serialise it once and write each stamp into those bytes
    (``runtime.exchange.prepare_outputs``). A mark holds for the step that makes it: mark
    the message at every step that returns it. Returns ``msg``."""
    _MARKED[id(msg)] = (msg, None, False)
    return msg


def quiet_message(msg: Any) -> Any:
    """Mark ``msg`` as ``constant_message`` does, and as standing for nothing published:
    what a topic carries while its publisher has nothing to say (an inactive controller's
    topics: upstream's publishes nothing). Lockstep wants a message of every due topic, so
    the step gives one; the runtime leaves it out where no node of the run takes the topic
    (``NodePlan.unconsumed``: nothing waits for it), and publishes it where one does.
    Returns ``msg``."""
    _MARKED[id(msg)] = (msg, None, True)
    return msg


def encoded_message(msg: Any, tail: bytes) -> Any:
    """Mark ``msg``, an output of the step now running whose first field is a
    std_msgs/Header, as serialising to ``tail`` past its header's stamp (CDR, as
    ``runtime.cdr.encode.encode`` writes it): a step that packs a message of a fixed layout
    at once hands the bytes with it, and the runtime only writes the tick's stamp in front
    of them. The maker answers for the bytes (a test compares them with ``encode``). A mark
    holds for the step that makes it. Returns ``msg``."""
    _MARKED[id(msg)] = (msg, tail, False)
    return msg


def take_output_marks() -> dict[int, tuple[Any, bytes | None, bool]] | None:
    """The messages marked (``constant_message``, ``quiet_message``, ``encoded_message``)
    since the last call, by id, with their bytes past the stamp (None for a constant one)
    and whether they may be left out, forgotten here:
    the runtime takes them right after each step, so the marks held are one step's (None
    when there are none)."""
    if not _MARKED:
        return None
    marks = dict(_MARKED)
    _MARKED.clear()
    return marks


@dataclass(frozen=True)
class Tick:
    """One exchange period: index ``k`` and its time in whole nanoseconds, ``k * tick_ns``
    rounded half up once (``plan.timeutil.tick_time_ns``; exact for a whole-ns tick)."""

    index: int
    time_ns: int


@dataclass(frozen=True)
class NodeConfig:
    """What a node is told at reset: its name, parameters, world, timing and the scenario goal."""

    name: str
    params: BaseModel
    tick_ns: Ns  # exact, a Fraction where not whole ns (30 Hz: period 100000000/3)
    period_ns: Ns
    world: Path | None = None
    goal: dict[str, float] | None = None
    joint_goal: dict[str, Any] | None = None  # {positions: {joint: rad}, tolerance: rad}
    scenario_dir: Path = field(default_factory=Path.cwd)
    render_warm_up: bool = True  # a camera builds its GL renderer in a thread at set-up
    robots: tuple[RobotModel, ...] = ()  # the robots this node serves, read once from the
    # description (descriptions.robot_reader): the world node's every robot, a robot's
    # node (NAME@ROBOT) its own, a scenario of one robot its one (unnamed) robot
    swarm: tuple[RobotModel, ...] = ()  # every robot of a swarm's world (those that enter
    # later too), as ``robots`` has them, for a robot's node that sees the others (its
    # lidar: their bases); () without a swarm
    layout: RobotsLayout | None = None  # a swarm: how its world is built from ``world`` (the
    # arena) and where each robot goes; None: ``world`` is the whole world
    events: tuple[EventSpec, ...] = ()  # the scenario's events (plan.events): objects
    # that enter and leave the world at given times, applied by every node with a world
    held_inputs: frozenset[str] = frozenset()  # its inputs (own names) fed by the external
    # node, which republishes the latest message from outside at every tick: one equal to
    # the last (but for its header's stamp) is held, not new

    @property
    def robot(self) -> RobotModel:
        """The one robot this node serves; a ValueError when it serves none or several."""
        if len(self.robots) != 1:
            raise ValueError(f"node {self.name} serves {len(self.robots)} robots, not one "
                             "(a world without the robot, or the world node of a swarm)")
        return self.robots[0]


class NoParams(BaseModel):
    """Parameters of a node that takes none: any key is refused."""

    model_config = ConfigDict(extra="forbid")


def node_seed(scenario_seed: int, node_name: str) -> int:
    """A 64-bit seed derived from the scenario seed and the node name, stable across runs."""
    digest = hashlib.sha256(f"{scenario_seed}:{node_name}".encode()).digest()
    return int.from_bytes(digest[:8], "little")


class StepNode:
    """Base class of every node's logic.

    Subclasses set ``Params`` (a pydantic model, checked when the scenario loads),
    ``needs_world`` and implement ``outputs``, ``step`` and optionally ``setup`` and
    ``metrics``. ``step`` returns one message per declared output topic, and at the first
    activation also one per ``latched_outputs`` topic. ``note`` tells people something
    (the runtime has no other way out of a step: a node never logs).
    """

    Params: ClassVar[type[BaseModel]] = NoParams
    needs_world: ClassVar[bool] = False
    runtime_params: ClassVar[frozenset[str]] = frozenset()
    """Top-level keys of ``Params`` that may change while the run goes (the node reads them
    from ``self.params`` at every step); the others are fixed once the node is set up."""
    type_keys: ClassVar[dict[str, str]] = {}  # topic -> the parameter that sets its type
    shares_inputs: ClassVar[bool] = False
    """Its step only reads the input messages it is given (never changes one, returns one as
    an output or keeps one to change later): the nodes of one process that read the same
    sample then get one decoded message between them (``runtime.exchange.SharedDecoder``)."""
    every_robot: ClassVar[bool] = False
    """The world node: one instance steps every robot of a swarm. It declares its topics for
    one robot; the plan publishes and feeds each robot's under the robot's namespace
    (``plan.robots.per_robot``), the shared ones (``/tf``, ``/cosim/...``) once."""
    hardware_role: ClassVar[bool] = False
    """The robot's controller manager: checked as a node of its own, then folded by the plan
    into the world node, which runs it in its step over MjData (``plan.hardware_wiring``,
    ``nodes.ros2_control.hosted``)."""

    @classmethod
    def description_names(cls, params: BaseModel) -> dict[str, Any]:
        """The names of the robot description this node's parameters give (field of
        ``descriptions.robot_reader.RobotNames`` -> name: ``base_body``, ``wheel_joints``,
        ``laser_site``, ...), which the description loader reads the robot model by instead
        of cosim's conventions. Nothing by default."""
        return {}

    @classmethod
    def outputs(cls, params: BaseModel) -> dict[str, type]:
        """Topic -> ROS 2 message class of everything this node publishes each activation."""
        raise NotImplementedError

    @classmethod
    def latched_outputs(cls, params: BaseModel) -> dict[str, type]:
        """Topic -> ROS 2 message class of what this node publishes once, latched: ``step``
        returns these at the node's first activation after each reset (with its ``outputs``)
        and never again. They go out with transient-local durability, so a subscriber that
        joins later still receives them (``/tf_static``); no scheduled input may take them.
        Nothing by default."""
        return {}

    @classmethod
    def rendered_outputs(cls, params: BaseModel) -> frozenset[str]:
        """The own names of the outputs drawn by a GL renderer (camera images): their bits
        depend on the renderer and its version (GPU or software), not only on the inputs,
        so digest comparisons can be asked to leave them out. None by default."""
        return frozenset()

    @classmethod
    def input_types(cls, params: BaseModel) -> dict[str, type]:
        """Input topic -> the message class this node takes on it, where it cares; the
        scenario is refused when the topic's producer publishes another type. ``type_keys``
        names the parameter that chooses the type, for that message. Nothing by default."""
        return {}

    @classmethod
    def client_inputs(cls, params: BaseModel) -> dict[str, str]:
        """Input topic -> ROS 2 type name ('std_msgs/msg/Float64MultiArray') of what ROS 2
        clients may send this node in an interactive scenario, beyond the goals and poses
        every node may take (plan/interactive.py): they enter through the external node at
        a tick boundary and are recorded. A topic the scenario wires to the node itself
        (its ``inputs:``) is left to that wiring. Nothing by default."""
        return {}

    @classmethod
    def world_problems(cls, params: BaseModel, model: Any, goal: dict[str, float] | None
                       ) -> list[tuple[str, str, str]]:
        """What makes this node unable to work in the world ``model`` (a compiled MjModel),
        checked when the scenario loads: (key, problem, accepted) per problem, the key
        relative to the node's entry (e.g. 'params.start') or, starting with 'goal', the
        scenario's goal. A world node of a swarm (``every_robot``) is also given its first
        robot's name, ``robot``, and its model where a description reader made it,
        ``described`` (its names are the model's, not the parameters'; None for an MJCF
        robot, read by the parameters' names once this check has passed). Nothing by
        default."""
        return []

    @classmethod
    def robot_problems(cls, params: BaseModel, robot: RobotModel, model: Any
                       ) -> list[tuple[str, str, str]]:
        """What this node needs of the robot model the run gives it (``robot``: the one it
        serves, or a swarm's first) in the world ``model`` (a compiled MjModel) and they lack
        (a lidar to cast from, a camera), checked when the scenario loads: (key, problem,
        accepted) as in ``world_problems``, worded for the robot's description format
        (``descriptions.robot_needs``), a key '' naming the node's entry. Nothing by
        default."""
        return []

    @classmethod
    def natural_rate(cls, params: BaseModel) -> int | None:
        """The rate in Hz this node's parameters decide (a controller manager's
        ``update_rate``), which a node the plan adds itself runs at; None by default."""
        return None

    @classmethod
    def period_problems(cls, params: BaseModel, model: Any, period_ns: int
                        ) -> list[tuple[str, str, str]]:
        """What makes this node's period ``period_ns`` unusable in the world ``model`` (a
        physics node whose period is not a whole number of the world's timesteps), checked
        when the scenario loads: (key, problem, accepted) as in ``world_problems``. Nothing
        by default."""
        return []

    @classmethod
    def world_warnings(cls, params: BaseModel, model: Any, goal: dict[str, float] | None,
                       start: dict[str, float] | None) -> list[tuple[str, str]]:
        """What will likely keep this node from doing its job in the world, though the run
        can start (a goal its map cannot reach, ...): (key, warning) per problem, keys as in
        ``world_problems``. ``start`` is the robot's start pose (x, y, yaw) when a node of the
        scenario sets one (a ``start`` parameter), else None. Nothing by default."""
        return []

    @classmethod
    def accepted_inputs(cls, params: BaseModel) -> set[str] | None:
        """The input topics this node understands, or None when it takes any topic."""
        return None

    def reset(self, seed: int, config: NodeConfig) -> None:
        """Start over: seed the generator, keep the config, then call ``setup``."""
        self.config = config
        self.params = config.params
        self.rng = np.random.default_rng(node_seed(seed, config.name))
        self._notes: list[str] = []
        self.setup()

    def setup(self) -> None:
        """Build the node's state from ``self.config``; called by ``reset``."""

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Advance to ``tick`` given the scheduled input messages; return the output messages."""
        raise NotImplementedError

    def set_params(self, params: BaseModel) -> None:
        """Take checked parameters whose ``runtime_params`` changed, from the next step on
        (a change from outside, at a tick boundary); a reset goes back to the scenario's."""
        self.params = params

    def metrics(self) -> dict[str, float]:
        """Numbers this node contributes to the run's outcome (collisions, goal reached, ...)."""
        return {}

    def note(self, text: str) -> None:
        """Tell people something about this step (why the node stands still, what it could
        not do). Not an output, not in the digest: the driver takes the notes after the step,
        with its tick, into the node's log, the run's manifest and its summary."""
        self.__dict__.setdefault("_notes", []).append(str(text))

    def take_notes(self) -> list[str]:
        """The notes made since the last call (drivers call it after every step)."""
        notes = self.__dict__.get("_notes")
        if not notes:
            return []
        self._notes = []
        return notes
