"""The whole plan is checked once, by the orchestrator: a node process it execs takes the
checked plan (``--plan``) instead of loading and checking the scenario again, and gives the
same result; a plan of another file is refused."""

from __future__ import annotations

import json

import pytest

from descriptions.load import load_scenario
from orchestrator.lockstep.supervisor import node_argv, write_checked_plan
from runtime.cosim_node import checked_plan
from tests.helpers import SCENARIOS, orchestrate

PROTOCOL = SCENARIOS / "protocol.yaml"


def test_the_checked_plan_is_the_scenario_and_only_its_own(tmp_path):
    scenario = load_scenario(PROTOCOL)
    path = write_checked_plan(scenario, tmp_path / "plan.pickle")
    assert path is not None
    back = checked_plan(path, PROTOCOL)
    assert list(back.nodes) == list(scenario.nodes)
    assert back.schedule.order == scenario.schedule.order
    assert back.tick_ns == scenario.tick_ns and back.model == scenario.model
    argv = node_argv(PROTOCOL, "any", ["source"], tmp_path, {}, None, path)
    assert argv[-2:] == ["--plan", str(path)]
    with pytest.raises(ValueError, match="not the checked plan"):
        checked_plan(path, SCENARIOS / "other.yaml")
    (tmp_path / "bad.pickle").write_bytes(b"not a pickle")
    with pytest.raises(ValueError, match="cannot read"):
        checked_plan(tmp_path / "bad.pickle", PROTOCOL)


def test_exec_nodes_take_the_checked_plan_and_give_the_forked_digest(tmp_path):
    forked = orchestrate(PROTOCOL, tmp_path / "fork", "--pack", "kind")
    execed = orchestrate(PROTOCOL, tmp_path / "exec", "--pack", "kind", "--spawn", "exec")
    assert forked.code == 0 and execed.code == 0, execed.stderr
    assert (execed.run_dir / "plan.pickle").is_file()
    manifests = [json.loads((r.run_dir / "manifest.json").read_text())
                 for r in (forked, execed)]
    assert [m["startup"]["node_processes"] for m in manifests] == ["fork", "exec"]
    assert manifests[0]["digest"] == manifests[1]["digest"]


def test_a_node_module_beside_the_scenario_loads_in_an_execd_process(tmp_path):
    """A ``module:`` node in the scenario's own folder (not installed, not in the working
    directory) is importable in a process that takes the checked plan, as in one that loads
    the scenario: its parameters' class is in the plan."""
    import yaml

    from tests.helpers import ROOT

    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "distance_node.py").write_text((ROOT / "examples" / "distance_node.py").read_text())
    doc = yaml.safe_load((ROOT / "examples" / "distance.yaml").read_text())
    doc["world"] = str(ROOT / "scenarios" / "worlds" / "nav.xml")
    doc["duration"] = "1s"
    (folder / "distance.yaml").write_text(yaml.safe_dump(doc))
    done = orchestrate(folder / "distance.yaml", tmp_path / "out", "--spawn", "exec")
    assert done.code in (0, 1), done.stderr  # 1 s does not reach the goal
    assert done.manifest["startup"]["node_processes"] == "exec"
