"""The built-in controller run as a plain rclpy program (examples/control_as_ros_node.py),
fed /odom and /scan as a foreign program, gives the built-in controller's digest; and the
start-up errors of foreign programs name the program."""

from __future__ import annotations

import time

import yaml

from tests.helpers import ROOT, SCENARIOS, orchestrate

NAV = ROOT / "scenarios" / "nav.yaml"
CONTROLLER = ROOT / "examples" / "control_as_ros_node.py"


def nav_with_foreign_control(tmp_path, duration="3s"):
    """nav.yaml (camera left out) with its control node replaced by the rclpy program."""
    doc = yaml.safe_load(NAV.read_text())
    doc["duration"] = duration
    doc["world"] = str((NAV.parent / doc["world"]).resolve())
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] != "camera"]
    builtin = tmp_path / "builtin.yaml"
    builtin.write_text(yaml.safe_dump(doc))
    control = next(n for n in doc["nodes"] if n["name"] == "control")
    control.pop("kind")
    control.pop("params", None)
    control["command"] = ["python", str(CONTROLLER), "--ros-args", "-p",
                          f"scenario:={builtin}"]
    control["params"] = {"outputs": {"/cmd_vel": "geometry_msgs/msg/Twist",
                                     "/plan": "nav_msgs/msg/Path"}}
    foreign = tmp_path / "foreign.yaml"
    foreign.write_text(yaml.safe_dump(doc))
    return builtin, foreign


def test_the_controller_as_a_ros_program_gives_the_builtin_digest(tmp_path):
    builtin, foreign = nav_with_foreign_control(tmp_path)
    ours = orchestrate(builtin, tmp_path / "a", "--in-process")
    theirs = orchestrate(foreign, tmp_path / "b")
    assert ours.code == theirs.code == 1, theirs.stderr  # 3 s: the goal is not reached yet
    assert theirs.manifest["digest"] == ours.manifest["digest"]


def scenario_with(tmp_path, command: list[str], inputs=None, start="4s"):
    doc = yaml.safe_load((SCENARIOS / "foreign_fusion.yaml").read_text())
    program = doc["nodes"][3]
    program["command"] = command
    if inputs is not None:
        program["inputs"] = inputs
    doc["deadlines"]["start"] = start
    path = tmp_path / "program.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_a_command_that_does_not_exist_is_bad_input(tmp_path):
    done = orchestrate(scenario_with(tmp_path, ["no-such-program-here", "--x"]), tmp_path / "r")
    assert done.code == 2 and "no program 'no-such-program-here' on PATH" in done.stderr
    assert "nodes[3] (fusion).command" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "r").exists()
    script = orchestrate(scenario_with(tmp_path, ["python", "missing.py"]), tmp_path / "r")
    assert script.code == 2 and "the script 'missing.py' does not exist" in script.stderr


def test_the_python_gate_for_a_program_that_is_not_python_is_refused(tmp_path):
    path = scenario_with(tmp_path, ["cat"])
    doc = yaml.safe_load(path.read_text())
    doc["nodes"][3]["params"]["gate"] = "python"
    path.write_text(yaml.safe_dump(doc))
    done = orchestrate(path, tmp_path / "r")
    assert done.code == 2 and "'cat' is not a Python program" in done.stderr, done.stderr
    assert "nodes[3] (fusion).params.gate" in done.stderr and not (tmp_path / "r").exists()


def test_a_program_that_is_not_python_gets_the_rmw_gate(tmp_path):
    # a shell never subscribes: what was refused for a non-Python program with several
    # inputs now starts behind the RMW gate, and is named at the start deadline
    done = orchestrate(scenario_with(tmp_path, ["sh", "-c", "exec sleep 30", "sh"], start="2s"),
                       tmp_path / "r")
    assert done.code == 3, done.stderr
    assert "never subscribed to its declared input /a" in done.stderr, done.stderr


def test_a_program_that_never_subscribes_a_declared_input_is_named(tmp_path):
    fusion = str(SCENARIOS.parent / "programs" / "fusion.py")
    inputs = [{"topic": t, "mode": "same_tick"} for t in ("/a", "/b", "/c")]
    done = orchestrate(scenario_with(tmp_path, ["python", fusion, "--ros-args", "-p",
                                                "inputs:=2"], inputs), tmp_path / "r")
    assert done.code == 3, done.stderr
    assert "node fusion" in done.stderr
    assert "never subscribed to its declared input /c" in done.stderr


def test_a_program_that_dies_before_it_is_ready_ends_the_run_quickly(tmp_path):
    started = time.monotonic()
    done = orchestrate(scenario_with(tmp_path, ["python", "-c", "import sys; sys.exit(5)"],
                                     start="60s"), tmp_path / "r")
    assert done.code == 3, done.stderr
    assert "node fusion died" in done.stderr and "exit code 5" in done.stderr
    assert time.monotonic() - started < 15  # start-up included; never the 60 s deadline
