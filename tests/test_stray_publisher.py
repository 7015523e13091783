"""A publisher that is not the scenario's on a run's topic is named, with the remedy, and
nothing is said to be lost: while the run goes, and at its start (issue 40, item 2)."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import yaml

from orchestrator.domains import DomainLease
from tests.helpers import ORCHESTRATE, ROOT, nav_without_camera_doc, orchestrate

TELEOP = [sys.executable, str(ROOT / "tests" / "programs" / "teleop.py"), "teleop_left_running"]


def _nav(tmp_path, duration: str):
    path = tmp_path / "nav.yaml"
    path.write_text(yaml.safe_dump(nav_without_camera_doc(duration)))
    return path


def _assert_named(stderr: str) -> None:
    assert "a publisher that is not the scenario's writes to /cmd_vel: " \
           "node /teleop_left_running" in stderr, stderr[-3000:]
    assert "Nothing was lost" in stderr
    assert "a message was lost" not in stderr
    assert "Remedy: stop that node, or give the run a ROS domain of its own" in stderr


def test_a_teleop_appearing_mid_run_is_named_not_called_a_lost_message(tmp_path):
    scenario = _nav(tmp_path, "60s")
    with DomainLease(wait_s=30) as domain:
        env = {**os.environ, "ROS_DOMAIN_ID": str(domain)}
        run = subprocess.Popen([*ORCHESTRATE, str(scenario), "--out", str(tmp_path / "out")],
                               cwd=ROOT, env=env, text=True, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
        teleop = None
        try:
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline:  # until ticks are being recorded
                parts = list((tmp_path / "out").glob("*/parts/physics.rec"))
                if parts and parts[0].stat().st_size > 5000:
                    break
                assert run.poll() is None, run.communicate()
                time.sleep(0.1)
            teleop = subprocess.Popen(TELEOP, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                                      text=True)
            _, err = run.communicate(timeout=120)
        finally:
            if teleop is not None:
                teleop.kill()
                teleop.communicate()
            if run.poll() is None:
                run.kill()
                run.communicate()
    assert run.returncode == 3, err[-3000:]
    _assert_named(err)


def test_a_teleop_already_there_stops_the_run_before_its_first_tick(tmp_path):
    scenario = _nav(tmp_path, "2s")
    with DomainLease(wait_s=30) as domain:
        env = {**os.environ, "ROS_DOMAIN_ID": str(domain)}
        teleop = subprocess.Popen(TELEOP, cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
        try:
            assert teleop.stdout.readline().strip() == "up"  # there before the run starts
            result = orchestrate(scenario, tmp_path / "out", env=env)
        finally:
            teleop.kill()
            teleop.communicate()
    assert result.code == 3, result.stderr[-3000:]
    _assert_named(result.stderr)
    # the node that reads /cmd_vel names it at start, or the orchestrator's graph check does
    assert ", 0 ticks" in result.stdout


def test_publishers_not_the_runs_are_told_apart_from_its_own():
    from runtime.intruders import describe, strangers

    assert strangers(["/cosim_physics"]) == []
    assert strangers(["/cosim_control", "/teleop"]) == ["/teleop"]
    # the same cosim node twice: another run of a scenario on this domain
    assert strangers(["/cosim_control", "/cosim_control"]) == ["/cosim_control"]
    text = describe("/cmd_vel", ["/teleop", "/cosim_control"])
    assert text.startswith("publishers that are not the scenario's write to /cmd_vel: ")
    assert "node /cosim_control (a node of another cosim run?)" in text


def test_a_stray_publisher_on_a_topic_that_drives_a_node_is_named_at_start(tmp_path):
    # /middle drives tail (same_tick): the stray's messages, numbered from 1 like the
    # scenario's, would start tail ticking on its own before the run's first tick
    doc = yaml.safe_load((ROOT / "tests" / "scenarios" / "long_chain.yaml").read_text())
    doc["duration"], doc["deadlines"] = "2s", {"start": "8s", "tick": "2s"}
    scenario = tmp_path / "chain.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    with DomainLease(wait_s=30) as domain:
        env = {**os.environ, "ROS_DOMAIN_ID": str(domain)}
        stray = subprocess.Popen([sys.executable, "-m", "bench.faults", "--publish", "/middle"],
                                 cwd=ROOT, env=env)
        try:
            time.sleep(1.0)
            result = orchestrate(scenario, tmp_path / "out", env=env)
        finally:
            stray.kill()
            stray.communicate()
    assert result.code == 3, result.stderr[-3000:]
    assert "writes to /middle: node /stray_publisher" in result.stderr, result.stderr[-3000:]
    assert "Nothing was lost" in result.stderr
