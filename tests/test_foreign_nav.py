"""The built-in controller run as a plain rclpy program (examples/control_as_ros_node.py),
fed /odom and /scan as a foreign program, gives the built-in controller's digest; and the
start-up errors of foreign programs name the program."""

from __future__ import annotations

import yaml

from tests.helpers import ROOT, SCENARIOS, nav_without_camera_doc, orchestrate

CONTROLLER = ROOT / "examples" / "control_as_ros_node.py"


def nav_with_foreign_control(tmp_path, duration="3s"):
    """nav.yaml (camera left out) with its control node replaced by the rclpy program."""
    doc = nav_without_camera_doc(duration)
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


def test_a_program_that_dies_before_it_is_ready_ends_the_run_without_its_deadline(tmp_path):
    # the start deadline is far beyond the hang guard: only noticing the death ends it in time
    done = orchestrate(scenario_with(tmp_path, ["python", "-c", "import sys; sys.exit(5)"],
                                     start="3600s"), tmp_path / "r", timeout=240)
    assert done.code == 3, done.stderr
    assert "node fusion died" in done.stderr and "exit code 5" in done.stderr


NAV_FOREIGN = ROOT / "scenarios" / "nav_foreign.yaml"
WAYPOINTS = [-2.62, -2.52, -2.47, -2.02, -1.97, -1.62, -1.47, -1.52]


def timer_driven_nav(tmp_path):
    """nav_foreign.yaml with the controller in its timer-driven shape (the odometry callback
    stores, a 10 Hz sim-time timer publishes /cmd_vel; fed /odom at 50 Hz) and a short
    route: the first waypoints of the full one (no lidar: nothing reads /scan)."""
    doc = yaml.safe_load(NAV_FOREIGN.read_text())
    doc["world"] = str((NAV_FOREIGN.parent / doc["world"]).resolve())
    doc["duration"] = "20s"
    doc["goal"] = {"x": WAYPOINTS[-2], "y": WAYPOINTS[-1], "yaw": 0.0,
                   "position_tolerance": 0.25, "yaw_tolerance": 0.3}
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] != "lidar"]
    control = next(n for n in doc["nodes"] if n["name"] == "controller")
    control["command"] = ["python", str(ROOT / "examples" / "waypoint_controller.py"),
                          "--ros-args", "-p", f"waypoints:={WAYPOINTS}".replace(" ", ""),
                          "-p", "goal_yaw:=0.0", "-p", "timer_hz:=10.0"]
    path = tmp_path / "timer_nav.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_a_timer_driven_controller_drives_nav_to_its_goal(tmp_path):
    """Nothing is published before the timer first fires (tick 5): physics sees none yet
    and the robot stands still; then it holds each command for 5 ticks, reaches the goal,
    and a run with both cores busy gives the same digest."""
    from orchestrator.outputs.bag import BagReader
    from tests.test_foreign_determinism import every_core_busy

    path = timer_driven_nav(tmp_path)
    runs = [orchestrate(path, tmp_path / "idle")]
    with every_core_busy():
        runs.append(orchestrate(path, tmp_path / "loaded"))
    for run in runs:
        assert run.code == 0, run.stderr  # 0: the goal was reached
    assert runs[0].manifest["digest"] == runs[1].manifest["digest"]
    tick_ns = runs[0].manifest["tick_ns"]
    with BagReader(runs[0].run_dir / "bag") as bag:
        commands = [stamp // tick_ns for stamp, _ in bag.messages("/cmd_vel")]
        odom = {stamp // tick_ns: msg for stamp, msg in bag.messages("/odom")}
    last = max(odom)
    assert commands == list(range(5, last + 1, 5))  # 10 Hz on sim time, from one period in
    # none yet until tick 5's command reaches physics at tick 6 (delayed): it stands still
    assert all(abs(odom[t].twist.twist.linear.x) < 1e-3 for t in range(6))
    assert odom[6].twist.twist.linear.x > 0.01
    assert odom[last].pose.pose.position.x > -1.8
