"""The lockstep core with real node processes over real rclpy: digests and protocol errors."""

from __future__ import annotations

import pytest
import yaml

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from tests.helpers import ORCHESTRATE, SCENARIOS, orchestrate

PROTOCOL = SCENARIOS / "protocol.yaml"


@pytest.fixture(scope="module")
def reference_digest() -> str:
    """The in-process digest of the protocol scenario: the reference."""
    return run_in_process(load_scenario(PROTOCOL)).digest


def variant(tmp_path, **changes) -> object:
    """A copy of the protocol scenario with top-level keys or node entries changed."""
    doc = yaml.safe_load(PROTOCOL.read_text())
    for name, node_changes in changes.pop("nodes", {}).items():
        next(n for n in doc["nodes"] if n["name"] == name).update(node_changes)
    doc.update(changes)
    path = tmp_path / "variant.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_two_multi_process_runs_equal_the_in_process_reference(tmp_path, reference_digest):
    first = orchestrate(PROTOCOL, tmp_path)
    second = orchestrate(PROTOCOL, tmp_path)
    assert first.code == 0, first.stderr
    assert second.code == 0, second.stderr
    assert first.manifest["digest"] == second.manifest["digest"] == reference_digest
    assert first.manifest["ticks"] == 101
    assert reference_digest in first.stdout


def test_cli_in_process_run_writes_the_same_digest(tmp_path, reference_digest):
    run = orchestrate(PROTOCOL, tmp_path, "--in-process")
    assert run.code == 0, run.stderr
    assert run.manifest["digest"] == reference_digest
    assert run.manifest["transport"] == "in-process"


def test_shuffled_start_order_and_a_slowed_node_change_nothing(tmp_path, reference_digest):
    shuffled = orchestrate(PROTOCOL, tmp_path, "--shuffle-start", "3")
    slowed = orchestrate(variant(tmp_path, nodes={"middle": {"debug": {"step_delay": "10ms"}},
                                                   "sink": {"debug": {"step_delay": "5ms"}}}),
                         tmp_path)  # sink is a leaf: it may lag behind; nothing may change
    assert shuffled.code == 0 and slowed.code == 0, shuffled.stderr + slowed.stderr
    assert shuffled.manifest["digest"] == reference_digest
    assert slowed.manifest["digest"] == reference_digest
    # the debug delay is not counted as step time: the mean stays below the delay itself
    # (a comparison with the scenario's own delay, which any counting of it would exceed)
    assert slowed.manifest["nodes"]["middle"]["step_ms_mean"] < 10


def test_seed_changes_the_digest(tmp_path, reference_digest):
    other = run_in_process(load_scenario(PROTOCOL, {"seed": 8})).digest
    assert other != reference_digest


def test_a_wall_clock_node_is_caught_by_the_digest(tmp_path):
    path = variant(tmp_path, nodes={"slow": {"kind": "wallclock"}})
    run = orchestrate(path, tmp_path)
    assert run.code == 0, run.stderr
    reference = run_in_process(load_scenario(path)).digest
    again = run_in_process(load_scenario(path)).digest
    assert len({run.manifest["digest"], reference, again}) == 3


def test_exception_in_step_names_node_tick_and_traceback(tmp_path):
    path = variant(tmp_path, nodes={"middle": {"kind": "faulty",
                                               "params": {"output": "/middle", "fail_at": 40}}})
    run = orchestrate(path, tmp_path)
    assert run.code == 3
    assert "node middle failed at tick 40" in run.stderr
    assert "RuntimeError: injected failure at tick 40" in run.stderr
    assert "testing.py" in run.stderr  # traceback excerpt
    assert run.stderr.count("injected failure at tick 40") <= 2  # once, plus its traceback line
    assert run.manifest["outcome"]["status"] == "failed"


def test_hung_node_misses_the_tick_deadline(tmp_path):
    path = variant(tmp_path, deadlines={"tick": "1s"},
                   nodes={"sink": {"kind": "faulty", "params": {"output": "/sink", "fail_at": 30,
                                                                 "mode": "hang"}}})
    run = orchestrate(path, tmp_path)
    assert run.code == 3
    assert "node sink did not finish tick 30 within the 1 s tick deadline" in run.stderr
    assert "process alive" in run.stderr
    assert "/middle of tick 30" in run.stderr


def test_start_deadline_names_the_node(tmp_path):
    # a node the user was to start and did not: never ready (a spawned node may be ready
    # before the orchestrator first looks, however short the deadline)
    run = orchestrate(variant(tmp_path, deadlines={"start": "1s"},
                              nodes={"sink": {"external": True}}), tmp_path)
    assert run.code == 3, run.stderr
    assert "start deadline of 1 s expired" in run.stderr
    assert "node sink (external process, started by you)" in run.stderr


def test_bad_scenario_exits_2_and_writes_nothing(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nduration: 1s\nnodes: []\n")
    out = tmp_path / "runs"
    run = orchestrate(bad, out)
    assert run.code == 2
    assert "bad.yaml: nodes" in run.stderr
    assert "Traceback" not in run.stderr
    assert not out.exists()


def test_help_explains_exit_codes():
    import subprocess

    out = subprocess.run([*ORCHESTRATE, "--help"],
                         capture_output=True, text=True, check=True).stdout
    for needle in ("--in-process", "exit codes", "130", "bad input"):
        assert needle in out
