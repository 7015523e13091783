"""The nav scenarios end to end with real node processes over ROS 2."""

from __future__ import annotations

import pytest

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from tests.helpers import ROOT, orchestrate

SCENARIOS = ROOT / "scenarios"


def test_nav_reaches_the_goal_with_the_in_process_digest(tmp_path):
    run = orchestrate(SCENARIOS / "nav.yaml", tmp_path)
    assert run.code == 0, run.stderr
    manifest = run.manifest
    assert manifest["outcome"]["success"] is True
    assert manifest["outcome"]["collisions"] == 0
    metrics = manifest["outcome"]["metrics"]
    assert metrics["goal_reached"] == 1.0
    assert 0 < metrics["time_to_goal"] < 60
    assert metrics["path_length"] > 8.5  # longer than the blocked straight line (8.5 m)
    assert manifest["digest"] == run_in_process(load_scenario(SCENARIOS / "nav.yaml")).digest


@pytest.mark.parametrize("name", ["corridor", "cluttered", "u_trap"])
def test_other_worlds_reach_the_goal_multi_process(tmp_path, name):
    run = orchestrate(SCENARIOS / f"{name}.yaml", tmp_path)
    assert run.code == 0, run.stderr
    assert run.manifest["outcome"]["collisions"] == 0


def test_goal_not_met_exits_1(tmp_path):
    run = orchestrate(SCENARIOS / "u_trap.yaml", tmp_path, "--duration", "3s", "--in-process")
    assert run.code == 1
    assert run.manifest["outcome"]["status"] == "goal_not_met"
