"""The gate tells the orchestrator when a foreign program's outputs match their readers, so
that the orchestrator need not wait out a settle time: the readers it is told to expect,
and when it says so (not before every output has a publisher matching them all)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from descriptions.load import load_scenario
from orchestrator.proxies.foreign_launch import gate_config, output_readers
from plan.packing import layout_of
from runtime.foreign_gate.cosim_gate import Gate, GateConfig
from tests.test_foreign_nav import nav_with_foreign_control


def test_each_output_expects_its_consumer_processes_and_the_orchestrator(tmp_path):
    _, foreign = nav_with_foreign_control(tmp_path)
    scenario = load_scenario(foreign)
    plan = scenario.nodes["control"]
    readers = output_readers(scenario, layout_of(scenario, None), plan)
    # /cmd_vel: physics and the orchestrator; /plan: only the orchestrator
    assert dict(zip(plan.gated_outputs, readers, strict=True)) == {"/cmd_vel": 2, "/plan": 1}
    config = GateConfig.from_json(json.dumps(gate_config(plan, scenario.schedule, readers)))
    assert config.readers == (2, 1)


def test_readers_must_name_one_count_per_output():
    with pytest.raises(ValueError, match="one count per output"):
        GateConfig.from_json(json.dumps({"prefix": "/cosim/feed/c/", "outputs": ["/a", "/b"],
                                         "readers": [1]}))


def publisher(topic: str, subscriptions: int):
    """A stand-in for an rclpy publisher: its topic and matched subscriptions."""
    return SimpleNamespace(topic_name=topic, get_subscription_count=lambda: subscriptions)


def view_of(*publishers):
    """A stand-in for the gate's view of an executor with one node."""
    node = SimpleNamespace(publishers=list(publishers))
    return SimpleNamespace(executor=SimpleNamespace(get_nodes=lambda: [node]))


@pytest.mark.parametrize(("publishers", "matched"), [
    ([publisher("/a", 2), publisher("/b", 1)], True),
    ([publisher("/a", 3), publisher("/b", 1), publisher("/other", 0)], True),
    ([publisher("/a", 1), publisher("/b", 1)], False),  # /a reaches one of its two readers
    ([publisher("/a", 2)], False),  # /b has no publisher yet
    ([publisher("/a", 2), publisher("/a", 0), publisher("/b", 1)], False),
])
def test_outputs_match_only_when_every_publisher_reaches_every_reader(publishers, matched):
    gate = Gate(GateConfig.from_json(json.dumps({
        "prefix": "/cosim/feed/c/", "outputs": ["/a", "/b"], "readers": [2, 1]})))
    assert gate._outputs_matched(view_of(*publishers)) is matched
