"""A controller manager whose update_rate is physics' rate / n (plan.schedule's topic periods,
nodes.ros2_control.hosted): it updates at every n-th physics activation, its controllers'
topics are published at those only, every driver agrees, and a ratio that is not whole is
refused naming the controllers file, its key and the rates accepted."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from helpers import ROOT, orchestrate

import nodes  # noqa: F401 - the node kinds, for load_scenario
from descriptions.load import load_scenario
from orchestrator.outputs.bag import BagReader
from plan.errors import ScenarioError
from plan.schedule import DELAYED, SAME_TICK, Edge, Schedule

ARM = ROOT / "scenarios" / "arm_control.yaml"
STATE = "/joint_trajectory_controller/controller_state"
GOAL = [-0.6, 0.4, 1.1, 0.5, -0.8, 0.3]  # arm_control's joint_goal

# -- the schedule ------------------------------------------------------------------------------

def test_a_topic_of_its_own_period_is_due_sampled_and_counted_at_its_ticks():
    # p publishes /fast every tick and /slow every 3rd; c (period 2) takes both same tick,
    # d (period 1) takes /slow delayed
    edges = [Edge("c", "p", "/fast", SAME_TICK), Edge("c", "p", "/slow", SAME_TICK),
             Edge("d", "p", "/slow", DELAYED)]
    s = Schedule(1, 20, {"p": 1, "c": 2, "d": 1}, edges, topic_periods={"/slow": 3})
    assert [k for k in range(21) if s.carries("p", "/slow", k)] == list(range(0, 21, 3))
    assert all(s.carries("p", "/fast", k) for k in range(21))
    assert s.inputs_at("c", 4) == [(0, 4), (1, 3)]  # the latest /slow at or before 4
    assert s.inputs_at("d", 4) == [(0, 3)] and s.inputs_at("d", 3) == [(0, 0)]
    assert s.samples("p", "/slow") == 7 and s.samples("p", "/fast") == 21
    assert s.samples("p", "/slow", until=7) == 3  # ticks 0, 3, 6
    assert s.activations("p") == 21  # the node acts every tick all the same
    assert s.driving_edge("c").topic == "/fast"  # /slow does not tell c each of its ticks
    # c takes /slow only at its every 4th tick (a manager in physics' step, at its updates)
    takes = Schedule(1, 20, {"p": 1, "c": 2}, edges[:2], topic_periods={"/slow": 3},
                     input_periods={("c", "/slow"): 4})
    assert takes.inputs_at("c", 2) == [(0, 2)] and takes.inputs_at("c", 4) == [(0, 4), (1, 3)]
    with pytest.raises(ValueError, match="whole multiple"):
        Schedule(1, 20, {"p": 2, "c": 2}, edges[:2], topic_periods={"/slow": 3})


# -- the run -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def slow_manager(tmp_path_factory) -> Path:
    """arm_control with physics at 200 Hz (a world of 1 ms timesteps) and the controllers
    file's update_rate 100: the trajectory controller active, sent one trajectory to the
    scenario's joint goal (nodes.testing.TrajectoryOnceNode)."""
    tmp = tmp_path_factory.mktemp("update_rate")
    world = (ARM.parent / "worlds" / "arm.xml").read_text()
    (tmp / "arm.xml").write_text(world.replace('timestep="0.002"', 'timestep="0.001"'))
    doc = yaml.safe_load(ARM.read_text())
    doc.update(world="arm.xml", duration="3s", interactive=False)
    physics, cm, arm = doc["nodes"]
    physics["rate"] = 200
    cm["params"]["controllers"] = str((ARM.parent / cm["params"]["controllers"]).resolve())
    cm["params"]["inactive"] = ["forward_position_controller"]
    cm.pop("remap")
    cm["inputs"] = [{"topic": "/joint_trajectory_controller/joint_trajectory",
                     "mode": "delayed"}]
    sender = {"name": "goal", "module": "nodes.testing:TrajectoryOnceNode", "rate": 10,
              "params": {"joints": arm["params"]["joints"], "positions": GOAL}}
    doc["nodes"] = [physics, cm, sender]
    path = tmp / "arm_slow_manager.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_a_manager_at_half_physics_rate_reaches_the_goal_one_digest_topics_at_its_rate(
        slow_manager, tmp_path):
    scenario = load_scenario(slow_manager)
    sched = scenario.schedule
    assert sched.periods["physics"] == 1 and sched.topic_period("physics", STATE) == 2
    assert sched.topic_period("physics", "/odom") == 1  # physics' own at its own rate
    assert sched.input_periods[("physics", "/joint_trajectory_controller/joint_trajectory")] == 2
    reference = orchestrate(slow_manager, tmp_path / "in", "--in-process")
    assert reference.code == 0, reference.stderr
    multi = orchestrate(slow_manager, tmp_path / "multi")
    assert multi.code == 0, multi.stderr
    manifest = multi.manifest
    assert manifest["digest"] == reference.manifest["digest"]
    assert manifest["outcome"]["success"] and manifest["outcome"]["stopped_early"]
    ticks = manifest["ticks"]
    with BagReader(multi.run_dir / "bag") as bag:
        for topic in (STATE, "/joint_states"):
            stamps = [s for s, _ in bag.messages(topic)]
            assert len(stamps) == sched.samples("physics", topic, until=ticks)
            steps = {b - a for a, b in zip(stamps, stamps[1:], strict=False)}
            assert steps == {10_000_000}  # 100 Hz
        assert bag.counts["/odom"] == ticks  # 200 Hz
        *_, (_, last) = bag.messages(STATE)
    assert max(abs(a - b) for a, b in zip(last.feedback.positions, GOAL, strict=True)) < 0.05


def test_an_update_rate_not_physics_rate_over_a_whole_number_is_refused(slow_manager):
    with pytest.raises(ScenarioError) as err:
        load_scenario(slow_manager, {"nodes.physics.rate": 150})  # 150 / 100 = 1.5
    text = str(err.value)
    assert "nodes[1] (controller_manager).rate" in text and str(slow_manager) in text
    assert "arm_controllers.yaml: controller_manager.ros__parameters.update_rate" in text
    assert "update_rate: one of 150, 75, 50, 30, 25, 15 Hz" in text
