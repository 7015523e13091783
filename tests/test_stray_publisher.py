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
    # nav reached its goal in 2 s of wall time, before a teleop started on a busy machine
    # was found: this run goes on however long the teleop takes to start
    scenario = _endless_nav(tmp_path)
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


def _endless_nav(tmp_path):
    """nav without its camera for 10 min of simulated time with a goal no pose meets: the run
    goes on for tens of seconds of wall time, until something stops it."""
    doc = nav_without_camera_doc("600s")
    doc["goal"]["position_tolerance"] = 1e-9
    path = tmp_path / "nav.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_a_teleop_already_there_stops_the_run_and_is_named(tmp_path):
    scenario = _endless_nav(tmp_path)
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
    # Named before the first tick when discovery has found it by the time every node is
    # ready (the graph check), else at its first message; a run that becomes ready within
    # discovery's latency (a fraction of a second on an idle machine) can be the second case.
    assert ", 0 ticks" in result.stdout or "among the scenario's numbered ones" in \
        result.stderr, result.stderr[-3000:]


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
    # long enough that discovery finds the stray within the run, ready or not at tick 0
    doc["duration"], doc["deadlines"] = "300s", {"start": "8s", "tick": "2s"}
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
