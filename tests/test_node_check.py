"""check_node runs a user's step class through cosim's rules and names what it breaks:
a wall clock, an undeclared topic, outputs that differ for the same seed, a latched output
after the first step; cosim's own nodes pass, and the README's example runs as written."""

from __future__ import annotations

import random
import re
from datetime import datetime
from time import monotonic
from typing import Any

import numpy as np
import pytest
from std_msgs.msg import Int64, String

from nodes.contract import NodeConfig, Tick
from nodes.control.node import ControlNode
from nodes.physics.node import PhysicsNode
from nodes.sensors.node import SensorsNode
from nodes.testing import ChatterNode, CounterNode
from orchestrator.api import check_node, load
from plan.timeutil import NS_PER_S
from runtime.build import node_config
from runtime.node_check import NODE_CHECKS, NodeCheckError
from tests.helpers import NAV, ROOT

COUNTER = {"output": "/count"}


def failures(node_class, params, **kwargs) -> dict[str, tuple[str, ...]]:
    """The failing checks of ``node_class`` and their problems; the exception agrees."""
    with pytest.raises(NodeCheckError) as caught:
        check_node(node_class, params, **kwargs)
    report = caught.value.report
    assert str(report) == str(caught.value)
    for name in report.failures:
        assert f"  {name}: " in str(report)
    return report.failures


class ClockNode(CounterNode):
    """Counts, and reads the monotonic clock through a name imported before the check."""

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Count; keep when (a read that decides nothing, still refused)."""
        self.last_step_s = monotonic()
        return super().step(tick, inputs)


class DateNode(CounterNode):
    """Publishes the day of the month."""

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Today's day."""
        return {self.params.output: Int64(data=datetime.now().day)}


class ExtraTopicNode(CounterNode):
    """Also publishes a topic it does not declare."""

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """The count, and a debug topic."""
        return {**super().step(tick, inputs), "/debug": String(data="hello")}


class UnseededNode(CounterNode):
    """Adds noise from a generator seeded by the OS, not from self.rng."""

    def setup(self) -> None:
        """A generator of its own, unseeded."""
        super().setup()
        self.noise = np.random.default_rng()

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Count plus noise."""
        out = super().step(tick, inputs)
        out[self.params.output].data += int(self.noise.integers(0, 1 << 30))
        return out


class GlobalRandomNode(CounterNode):
    """Adds noise from the global generators of Python and numpy."""

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Count plus noise."""
        out = super().step(tick, inputs)
        out[self.params.output].data += random.randint(0, 9) + int(np.random.randint(0, 9))
        return out


class LatchedAgainNode(ChatterNode):
    """Publishes its latched text at every step."""

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Every text, every time."""
        self.first = True
        return super().step(tick, inputs)


class LeakyNode(CounterNode):
    """Keeps its count in the class: a reset does not start it over."""

    total = 0

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """The running total over every instance and reset."""
        LeakyNode.total += 1
        return {self.params.output: Int64(data=LeakyNode.total)}


class SilentNode(CounterNode):
    """Forgets to return its outputs."""

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Count, return nothing."""
        super().step(tick, inputs)


def test_the_checks_are_named_and_documented():
    names = [c.name for c in NODE_CHECKS]
    assert len(names) == len(set(names)) and all(c.doc for c in NODE_CHECKS)
    assert {"declared_topics", "latched_first_step", "no_wall_clock", "no_unseeded_random",
            "same_seed_same_outputs"} <= set(names)
    report = check_node(CounterNode, {**COUNTER, "noise": 5})  # seeded noise is fine
    assert report.passed and not report.failures and "all 10 checks passed" in str(report)


def test_a_node_that_reads_the_wall_clock_is_named():
    found = failures(ClockNode, COUNTER)
    assert list(found) == ["no_wall_clock"]
    assert found["no_wall_clock"] == ("the steps at ticks 0, 1, 2 read the wall clock "
                                      "time.monotonic",)
    found = failures(DateNode, COUNTER)
    assert "the steps at ticks 0, 1, 2 read the wall clock datetime.now" in \
        found["no_wall_clock"]


def test_a_node_that_publishes_an_undeclared_topic_is_named():
    found = failures(ExtraTopicNode, COUNTER)
    assert list(found) == ["declared_topics"]
    assert found["declared_topics"][0] == ("step at tick 0 published /debug, not declared in "
                                           "outputs() or latched_outputs()")


def test_a_node_whose_outputs_differ_for_the_same_seed_is_named():
    found = failures(UnseededNode, COUNTER)
    assert set(found) == {"no_unseeded_random", "same_seed_same_outputs", "reset_replays"}
    assert found["no_unseeded_random"][0].startswith("reset drew random numbers from "
                                                     "os.urandom")
    [why] = found["same_seed_same_outputs"]
    assert re.fullmatch(r"at tick 0, /count differs \(a second instance, same seed\): "
                        r"data: \d+ vs \d+", why), why
    found = failures(GlobalRandomNode, COUNTER)
    assert any("the global random module" in p for p in found["no_unseeded_random"])
    assert any("numpy's global generator" in p for p in found["no_unseeded_random"])
    LeakyNode.total = 0
    found = failures(LeakyNode, COUNTER)
    assert list(found) == ["same_seed_same_outputs", "reset_replays"]
    assert found["reset_replays"] == ("at tick 0, /count differs (the first instance reset "
                                      "again): data: 1 vs 7",)


def test_a_latched_output_after_the_first_step_is_named():
    params = {"outputs": {"/chatter": "hi"}, "latched": {"/hello": "once"}}
    assert check_node(ChatterNode, params).passed
    found = failures(LatchedAgainNode, params)
    assert list(found) == ["latched_first_step"]
    assert found["latched_first_step"][0] == ("step at tick 1 published latched /hello again "
                                              "(latched outputs go out at the first step only)")


def test_setup_problems_are_reported_and_nothing_else_is_judged():
    report = check_node(CounterNode, {"output": 3}, check=False)
    assert list(report.failures) == ["valid_setup"] and not report.passed
    assert "do not fit CounterNode.Params" in report.failures["valid_setup"][0]
    assert "not run: no_exception" in str(report)
    assert "needs a world" in str(check_node(PhysicsNode, {}, check=False))
    raising = check_node(CounterNode, {"output": "/count"}, inputs={"/in": String()},
                         check=False)  # String has no .data of a number: the step raises
    assert list(raising.failures) == ["no_exception"]
    assert raising.failures["no_exception"][0].startswith("step at tick 0 raised TypeError")
    silent = check_node(SilentNode, COUNTER, check=False)
    assert silent.failures == {"no_exception": (
        "step at tick 0 returned NoneType, not a dict of topic -> message",)}


def test_cosim_nodes_pass_with_the_nav_scenario_params():
    scenario = load(NAV)
    configs = {name: node_config(scenario, name) for name in ("physics", "lidar", "control")}

    def checked(cls, name, inputs=None):
        config: NodeConfig = configs[name]
        return check_node(cls, config.params, world=config.world, goal=config.goal, name=name,
                          rate=NS_PER_S // config.period_ns, tick_rate=NS_PER_S // config.tick_ns,
                          seed=scenario.model.seed, inputs=inputs)

    assert checked(PhysicsNode, "physics").passed  # a default Twist on /cmd_vel
    physics = PhysicsNode()
    physics.reset(scenario.model.seed, configs["physics"])
    state = physics.step(Tick(0, 0), {})
    sensed = {"/cosim/world_state": state["/cosim/world_state"]}
    assert checked(SensorsNode, "lidar", sensed).passed
    lidar = SensorsNode()
    lidar.reset(scenario.model.seed, configs["lidar"])
    scan = lidar.step(Tick(0, 0), sensed)["/scan"]
    assert checked(ControlNode, "control", {"/odom": state["/odom"], "/scan": scan}).passed


def readme_example() -> str:
    """The Python block of the README's 'Writing your own node' section that runs
    check_node (the section's walk-through comes first)."""
    text = (ROOT / "docs" / "tutorials" / "own-node.md").read_text()
    section = text.split("## Writing your own node", 1)[1].split("\n## ", 1)[0]
    blocks = [b.split("```", 1)[0] for b in section.split("```python\n")[1:]]
    return next(b for b in blocks if "check_node(" in b)


def test_the_readme_example_runs_as_written(capsys):
    exec(compile(readme_example(), "README.md", "exec"), {"__name__": "readme"})  # noqa: S102
    assert "all 10 checks passed" in capsys.readouterr().out
