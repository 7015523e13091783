"""cosim-ros2, ros2cli's everyday verbs on a pip-only install, as a user types them: against
a standalone realtime physics node (topic list, info, echo, hz, pub moving the robot) and a
paused interactive run (service list and call, param get and set, action list and
send_goal, and the service call that stops the run)."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time

import pytest
import yaml

from orchestrator.ros2cli.messages import fill, interface_class, parse_values, to_plain
from tests.helpers import ROOT
from tests.live_helpers import cosim_node, finish, orchestrate

ROS2 = [sys.executable, "-m", "orchestrator.ros2cli"]
NAV = str(ROOT / "scenarios" / "nav.yaml")


def ros2(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    """Run cosim-ros2 with ``args`` and wait for it."""
    return subprocess.run([*ROS2, *args], capture_output=True, text=True, timeout=timeout,
                          cwd=ROOT)


def quit_run(run: subprocess.Popen) -> tuple[int, str]:
    """Stop a paused run with SetSimulationState STOPPED, as a user would; (its code, stderr).
    A run that outlives this is interrupted (and its code is then not the one returned)."""
    try:
        stop = ros2("service", "call", "/set_simulation_state",
                    "simulation_interfaces/srv/SetSimulationState", "{state: {state: 3}}")
        assert stop.returncode == 0, stop.stderr
        code, _, err = finish(run, timeout=60)
        return code, err
    finally:
        interrupt(run)


def interrupt(run: subprocess.Popen) -> None:
    """SIGINT to a run still going (a test that failed midway), and wait for it."""
    if run.poll() is None:
        run.send_signal(signal.SIGINT)
        finish(run, timeout=30)


def odom_x() -> float:
    """x of the robot on the next /odom, read with topic echo --once."""
    done = ros2("topic", "echo", "--once", "--timeout", "30", "/odom")
    assert done.returncode == 0, done.stderr
    odom = yaml.safe_load(done.stdout.split("\n---")[0])
    return odom["pose"]["pose"]["position"]["x"]


def test_values_types_and_errors_as_ros2cli_takes_them():
    twist = fill(interface_class("geometry_msgs/Twist", "msg")(),
                 parse_values("{linear: {x: 1}, angular: {z: -0.5}}"))
    assert to_plain(twist) == {"linear": {"x": 1.0, "y": 0.0, "z": 0.0},
                               "angular": {"x": 0.0, "y": 0.0, "z": -0.5}}
    assert interface_class("nav_msgs/msg/Path", "msg") is interface_class("nav_msgs/Path", "msg")
    path = fill(interface_class("nav_msgs/Path", "msg")(),
                parse_values("{poses: [{pose: {position: {x: 2}}}, {}]}"))
    assert [p.pose.position.x for p in path.poses] == [2.0, 0.0]
    for values, problem in [("{linear: {x: fast}}", "'linear.x' (double) cannot take 'fast'"),
                            ("{linar: {x: 1}}", "no field 'linar'"),
                            ("[1, 2]", "not a YAML mapping")]:
        with pytest.raises(ValueError, match=re.escape(problem)):
            fill(twist, parse_values(values))
    with pytest.raises(ValueError, match="pkg/msg/Name or pkg/Name"):
        interface_class("Twist", "msg")
    bad = ros2("topic", "pub", "/cmd_vel", "geometry_msgs/msg/Twist", "{linear: 1}")
    assert bad.returncode == 2 and "cannot take 1" in bad.stderr


def test_topic_verbs_drive_a_standalone_physics_node():
    physics = cosim_node("physics", "--scenario", NAV, "--realtime")
    try:
        start = odom_x()  # echo waits for the node to appear
        assert start == pytest.approx(-3.0, abs=0.01)
        listed = ros2("topic", "list", "-t", "--spin-time", "2")
        assert "/odom [nav_msgs/msg/Odometry]" in listed.stdout.splitlines()
        assert "/cmd_vel [geometry_msgs/msg/Twist]" in listed.stdout.splitlines()
        info = ros2("topic", "info", "/cmd_vel")
        assert info.stdout.splitlines() == ["Type: geometry_msgs/msg/Twist",
                                            "Publisher count: 0", "Subscription count: 1"]
        hz = ros2("topic", "hz", "/odom", "--duration", "2.5")
        rates = [float(line.split()[-1]) for line in hz.stdout.splitlines()
                 if line.startswith("average rate:")]
        assert rates and 25 < rates[-1] < 75  # 50 Hz on wall time, give or take the load
        pub = ros2("topic", "pub", "--once", "/cmd_vel", "geometry_msgs/Twist",
                   "{linear: {x: 0.5}}")
        assert pub.returncode == 0 and "publishing #1" in pub.stdout, pub.stderr
        deadline = time.monotonic() + 60  # the robot keeps the last command: it drives on
        while (x := odom_x()) < start + 0.2 and time.monotonic() < deadline:
            time.sleep(0.5)
        assert x > start + 0.2
    finally:
        physics.send_signal(signal.SIGINT)
        code, _, err = finish(physics, timeout=20)
    assert code == 0, err


def test_service_param_and_action_verbs_on_a_paused_run(tmp_path):
    run = orchestrate(ROOT / "scenarios" / "nav.yaml", tmp_path, "--paused",
                      "--set", "interactive=true")
    try:
        features = ros2("service", "call", "/get_simulator_features",
                        "simulation_interfaces/srv/GetSimulatorFeatures")
        assert features.returncode == 0, features.stderr
        reply = yaml.safe_load(features.stdout.split("response:\n", 1)[1])
        assert 32 in reply["features"]["features"]  # STEP_SIMULATION_ACTION
        services = ros2("service", "list", "-t", "--spin-time", "3").stdout.splitlines()
        assert "/control/set_parameters [rcl_interfaces/srv/SetParameters]" in services

        assert ros2("param", "get", "/control", "max_speed").stdout == "Double value is: 0.5\n"
        assert ros2("param", "set", "/control", "max_speed", "0.3").stdout == (
            "Set parameter successful\n")
        assert ros2("param", "get", "/control", "max_speed").stdout == "Double value is: 0.3\n"
        refused = ros2("param", "set", "/control", "resolution", "0.1")
        assert refused.returncode == 1 and "read-only" in refused.stdout

        actions = ros2("action", "list", "-t", "--spin-time", "3").stdout.splitlines()
        assert "/simulate_steps [simulation_interfaces/action/SimulateSteps]" in actions
        steps = ros2("action", "send_goal", "--feedback", "/simulate_steps",
                     "simulation_interfaces/action/SimulateSteps", "{steps: 3}")
        assert steps.returncode == 0, steps.stderr  # (feedback that comes before the client
        # has heard its goal accepted is dropped, as by any action client: not asserted)
        assert "3 step(s) done" in steps.stdout
        assert steps.stdout.rstrip().endswith("Goal finished with status: SUCCEEDED")
    except BaseException:
        interrupt(run)
        raise
    code, err = quit_run(run)
    assert code in (0, 1), err  # stopped before the goal: goal not met


def test_a_swarms_nodes_serve_their_parameters_under_their_robots_namespace(tmp_path):
    # control@robot_3 is no valid ROS 2 node name: the run's ROS interfaces once failed to
    # start on it, leaving servers that never answered (here and in later runs' clients)
    run = orchestrate(ROOT / "scenarios" / "swarm.yaml", tmp_path, "--paused", "--pack", "kind",
                      "--set", "interactive=true")
    try:
        got = ros2("param", "get", "/robot_3/control", "max_speed")
        assert got.stdout == "Double value is: 0.5\n", got.stderr
        assert ros2("param", "set", "/robot_3/control", "max_speed", "0.4").stdout == (
            "Set parameter successful\n")
        assert ros2("param", "get", "/robot_3/control", "max_speed").stdout == (
            "Double value is: 0.4\n")
        assert ros2("param", "get", "/robot_2/control", "max_speed").stdout == (
            "Double value is: 0.5\n")
    except BaseException:
        interrupt(run)
        raise
    code, err = quit_run(run)
    assert code in (0, 1), err
    assert "could not start" not in err
