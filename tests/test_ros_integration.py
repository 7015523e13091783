"""Fitting into a ROS 2 workflow: standalone nodes, external lockstep nodes, foreign
programs, remapping. Everything here runs real processes over real rclpy."""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time

import pytest
import yaml
from geometry_msgs.msg import Twist, Vector3
from nav_msgs.msg import Odometry

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from tests.helpers import COSIM_NODE, ORCHESTRATE, ROOT, SCENARIOS, orchestrate
from tests.test_supervision import bag_counts

ECHO = SCENARIOS / "foreign_echo.yaml"


def test_realtime_physics_is_driven_by_a_plain_rclpy_publisher(ros_node):
    node, executor = ros_node
    odoms: list[Odometry] = []
    node.create_subscription(Odometry, "/odom", odoms.append, 10)
    cmd = node.create_publisher(Twist, "/cmd_vel", 10)
    physics = subprocess.Popen([*COSIM_NODE, "physics", "--scenario",
                                str(ROOT / "scenarios" / "nav.yaml"), "--realtime", "--rtf", "2"],
                               cwd=ROOT, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30
        while not odoms and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert odoms, "no /odom from the standalone physics node"
        start = odoms[-1].pose.pose.position

        def moved() -> float:
            end = odoms[-1].pose.pose.position
            return ((end.x - start.x) ** 2 + (end.y - start.y) ** 2) ** 0.5

        deadline = time.monotonic() + 60  # a hang guard: the robot moves however slow the run
        while moved() <= 0.3 and time.monotonic() < deadline:
            cmd.publish(Twist(linear=Vector3(x=0.5)))
            executor.spin_once(timeout_sec=0.02)
        assert moved() > 0.3
    finally:
        physics.send_signal(signal.SIGINT)
        _, err = physics.communicate(timeout=10)
    assert physics.returncode == 0
    assert "Traceback" not in err
    assert "publishing /clock" in err


def test_foreign_program_runs_in_lockstep_twice_alike(tmp_path):
    first = orchestrate(ECHO, tmp_path)
    second = orchestrate(ECHO, tmp_path)
    assert first.code == 0, first.stderr
    assert second.code == 0, second.stderr
    assert first.manifest["digest"] == second.manifest["digest"]
    counts = bag_counts(first.run_dir)
    assert counts["/echoed"] == counts["/source"] == counts["/sink"] == 101


@pytest.mark.parametrize("copies,expected", [
    (2, "foreign node echo published 2 message(s) on /echoed at tick 0, and the scenario "
        "declares exactly 1 (params.per_activation./out)"),
    (0, "foreign node echo published 0 message(s) on /echoed at tick 0, and the scenario "
        "declares exactly 1 (params.per_activation./out)")])
def test_a_declared_count_that_the_program_breaks_is_named(tmp_path, copies, expected):
    doc = yaml.safe_load(ECHO.read_text())
    doc["nodes"][1]["command"][-1] = f"copies:={copies}"
    doc["nodes"][1]["params"]["per_activation"] = {"/out": 1}
    path = SCENARIOS / f"_echo_{copies}_{os.getpid()}.yaml"  # beside the program it runs
    path.write_text(yaml.safe_dump(doc))
    try:
        run = orchestrate(path, tmp_path)  # its timeout is the hang guard
    finally:
        path.unlink()
    assert run.code == 3
    assert expected in run.stderr


def test_nav_with_a_foreign_controller_reaches_the_goal_with_equal_digests(tmp_path):
    first = orchestrate(ROOT / "scenarios" / "nav_foreign.yaml", tmp_path)
    second = orchestrate(ROOT / "scenarios" / "nav_foreign.yaml", tmp_path)
    assert first.code == 0, first.stderr
    assert first.manifest["outcome"]["metrics"]["arrived"] == 1.0
    assert first.manifest["outcome"]["collisions"] == 0
    assert first.manifest["digest"] == second.manifest["digest"]


def test_external_lockstep_node_joins_the_run(tmp_path):
    doc = yaml.safe_load((SCENARIOS / "protocol.yaml").read_text())
    doc["nodes"][1]["external"] = True
    path = tmp_path / "external.yaml"
    path.write_text(yaml.safe_dump(doc))
    orchestrator = subprocess.Popen([*ORCHESTRATE, str(path),
                                     "--out", str(tmp_path / "runs"), "--quiet"], cwd=ROOT,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(orchestrator.stderr), daemon=True)
    reader.start()
    deadline = time.monotonic() + 60  # a hang guard
    # the node starts only once the orchestrator has asked for it, so it always joins late
    while not any("waiting for external node middle" in line for line in lines):
        assert orchestrator.poll() is None and time.monotonic() < deadline, lines
        time.sleep(0.05)
    node = subprocess.run([*COSIM_NODE, "counter", "--scenario", str(path),
                           "--node", "middle", "--lockstep"], cwd=ROOT, capture_output=True,
                          text=True, timeout=60)
    out = orchestrator.stdout.read()
    orchestrator.wait(timeout=60)
    reader.join(timeout=60)
    err = "".join(lines)
    assert orchestrator.returncode == 0, err
    assert node.returncode == 0, node.stderr
    assert run_in_process(load_scenario(path)).digest in out


def test_remapped_topics_appear_under_their_new_names(tmp_path):
    doc = yaml.safe_load((SCENARIOS / "protocol.yaml").read_text())
    doc["nodes"][4]["remap"] = {"/slow": "/renamed_slow"}  # its consumer takes /renamed_slow
    doc["nodes"][1]["inputs"][1]["topic"] = "/renamed_slow"
    doc["nodes"][0]["remap"] = {"/source": "/source_for_tools"}  # consumed under the new name
    doc["nodes"][1]["inputs"][0]["topic"] = "/source_for_tools"
    doc["nodes"][3]["remap"] = {"/sink": "/watched"}  # nobody consumes it: a warning
    path = tmp_path / "remap.yaml"
    path.write_text(yaml.safe_dump(doc))
    run = orchestrate(path, tmp_path / "runs")
    assert run.code == 0, run.stderr
    assert "warning" in run.stderr and "/watched is published but no node" in run.stderr
    counts = bag_counts(run.run_dir)
    assert {"/renamed_slow", "/source_for_tools", "/watched"} <= set(counts)
    assert not {"/slow", "/source", "/sink"} & set(counts)
