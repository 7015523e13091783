"""Small purpose-built nodes for protocol tests and benchmarks (not used by the nav scenario)."""

from __future__ import annotations

import os
import signal
import time
from typing import Any

from pydantic import BaseModel, ConfigDict
from std_msgs.msg import Float64, Int64, String

from nodes.contract import StepNode, Tick


class CounterParams(BaseModel):
    """Parameters of a counter: its output topic and an optional seeded noise amplitude."""

    model_config = ConfigDict(extra="forbid")
    output: str
    noise: int = 0


class CounterNode(StepNode):
    """Publishes Int64 = activations so far + tick index + sum of every input (+ seeded noise)."""

    Params = CounterParams

    @classmethod
    def outputs(cls, params: CounterParams) -> dict[str, type]:
        """One Int64 topic."""
        return {params.output: Int64}

    def setup(self) -> None:
        """Start counting from zero."""
        self.count = 0

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Count, add the inputs (in topic order) and publish."""
        self.count += 1
        value = self.count * 1000 + tick.index
        for topic in sorted(inputs):
            data = inputs[topic].data
            data = data if isinstance(data, int) else round(data * 1_000_000)
            value = (value * 31 + data) % (1 << 62)
        if self.params.noise:
            value += int(self.rng.integers(0, self.params.noise))
        return {self.params.output: Int64(data=value)}

    def metrics(self) -> dict[str, float]:
        """How many times it stepped."""
        return {"activations": float(self.count)}


class IntegratorParams(BaseModel):
    """Parameters of an integrator: output topic, gain on the input and initial value."""

    model_config = ConfigDict(extra="forbid")
    output: str
    gain: float = -0.5
    initial: float = 1.0


class IntegratorNode(StepNode):
    """x' = gain * u (or x' = 1 with no input): forward Euler over the node's own period."""

    Params = IntegratorParams

    @classmethod
    def outputs(cls, params: IntegratorParams) -> dict[str, type]:
        """One Float64 topic."""
        return {params.output: Float64}

    def setup(self) -> None:
        """Start at the initial value."""
        self.x = self.params.initial

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Integrate the input over one period; an absent input (tick 0 of a delayed edge) is 0."""
        u = sum(msg.data for _, msg in sorted(inputs.items())) if inputs else 1.0
        self.x += self.params.gain * u * self.config.period_ns / 1e9
        return {self.params.output: Float64(data=self.x)}


class WallClockNode(CounterNode):
    """Deliberately non-deterministic: publishes the wall time. The digest must catch it."""

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Publish time.time_ns(), which differs between runs."""
        return {self.params.output: Int64(data=time.time_ns())}


class FaultyParams(CounterParams):
    """A counter that fails on purpose at a given tick, in a given way."""

    fail_at: int = -1
    mode: str = "raise"  # raise | exit | hang | kill | setup | deaf (hangs, signals ignored)


class FaultyNode(CounterNode):
    """Counter that raises, exits, hangs or kills itself at ``fail_at`` (fault-injection tests)."""

    Params = FaultyParams

    def setup(self) -> None:
        """Fail at start when mode is 'setup' (a node that cannot load its world, say)."""
        if self.params.mode == "setup":
            raise RuntimeError("injected failure in setup")
        super().setup()

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Fail as configured at ``fail_at``, otherwise count."""
        if tick.index == self.params.fail_at:
            if self.params.mode == "raise":
                raise RuntimeError(f"injected failure at tick {tick.index}")
            if self.params.mode == "exit":
                os._exit(7)
            if self.params.mode == "kill":
                os.kill(os.getpid(), signal.SIGKILL)
            if self.params.mode == "deaf":  # a step stuck where no signal handler runs
                for sig in (signal.SIGINT, signal.SIGTERM):
                    signal.signal(sig, signal.SIG_IGN)
            if self.params.mode in ("hang", "deaf"):
                while True:
                    time.sleep(1)
        return super().step(tick, inputs)


class ChatterParams(BaseModel):
    """Parameters of a chatter: the text it publishes on each topic, every activation, and
    the text it publishes once, latched."""

    model_config = ConfigDict(extra="forbid")
    outputs: dict[str, str] = {}
    latched: dict[str, str] = {}


class ChatterNode(StepNode):
    """Publishes fixed std_msgs/String texts (the rosbridge conformance cases' messages);
    takes any input and ignores it."""

    Params = ChatterParams

    @classmethod
    def outputs(cls, params: ChatterParams) -> dict[str, type]:
        """A String topic per entry of ``outputs``."""
        return dict.fromkeys(params.outputs, String)

    @classmethod
    def latched_outputs(cls, params: ChatterParams) -> dict[str, type]:
        """A String topic per entry of ``latched``."""
        return dict.fromkeys(params.latched, String)

    def setup(self) -> None:
        """The latched texts go out at the first step after each reset."""
        self.first = True

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Every text of ``outputs`` (and of ``latched`` the first time)."""
        out = {topic: String(data=text) for topic, text in self.params.outputs.items()}
        if self.first:
            out.update({topic: String(data=text) for topic, text in self.params.latched.items()})
            self.first = False
        return out


class TrajectoryOnceParams(BaseModel):
    """The joints and the positions one trajectory takes them to (in ``seconds``)."""

    model_config = ConfigDict(extra="forbid")
    joints: list[str]
    positions: list[float]
    seconds: int = 1


class TrajectoryOnceNode(StepNode):
    """Publishes one JointTrajectory on a trajectory controller's ~/joint_trajectory at its
    first activation, then empty ones (which the controller ignores): a goal without a
    client, for ros2_control tests."""

    Params = TrajectoryOnceParams
    TOPIC = "/joint_trajectory_controller/joint_trajectory"

    @classmethod
    def outputs(cls, params: TrajectoryOnceParams) -> dict[str, type]:
        """The trajectory controller's topic."""
        from trajectory_msgs.msg import JointTrajectory

        return {cls.TOPIC: JointTrajectory}

    def setup(self) -> None:
        """Nothing sent yet."""
        self.sent = False

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """The trajectory at the first activation, empty ones after."""
        from builtin_interfaces.msg import Duration
        from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

        msg = JointTrajectory()
        if not self.sent:
            msg.joint_names = list(self.params.joints)
            msg.points = [JointTrajectoryPoint(positions=list(self.params.positions),
                                               time_from_start=Duration(sec=self.params.seconds))]
            self.sent = True
        return {self.TOPIC: msg}


class TakerParams(BaseModel):
    """Parameters of a taker: its output topic."""

    model_config = ConfigDict(extra="forbid")
    output: str


class TakerNode(StepNode):
    """Takes any topics (any message type) and publishes an Int64: the stamps' nanoseconds
    of what it took at this activation, summed (0 for a message without a header): a node
    of the run that takes a topic, whatever it carries."""

    Params = TakerParams

    @classmethod
    def outputs(cls, params: TakerParams) -> dict[str, type]:
        """One Int64 topic."""
        return {params.output: Int64}

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Sum the stamps taken."""
        total = sum(m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
                    for m in inputs.values() if hasattr(m, "header"))
        return {self.params.output: Int64(data=total)}
