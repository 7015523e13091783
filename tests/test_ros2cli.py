"""cosim-ros2, ros2cli's everyday verbs on a pip-only install, as a user types them: against
a standalone realtime physics node (topic list, info, echo, hz, pub moving the robot) and a
paused interactive run (service list and call, param get and set, action list and
send_goal, and the service call that stops the run); in a fresh shell (no ROS_DOMAIN_ID) it
finds the run going on this machine by itself, and the lines a run prints paste as they are."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from orchestrator.ros2cli.messages import fill, interface_class, parse_values, to_plain
from tests.helpers import ORCHESTRATE, ROOT
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


def fresh_shell(tmp: Path) -> dict[str, str]:
    """The environment of a new shell of this user: no ROS domain, no discovery range, and
    ``tmp`` as its TMPDIR (where runs claim their domains: the runs of other tests, elsewhere,
    stay out of sight)."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY")}
    tmp.mkdir(exist_ok=True)
    return {**env, "TMPDIR": str(tmp)}


def ros2_in(env: dict[str, str], *args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    """cosim-ros2 with ``args`` in the shell of ``env``."""
    return subprocess.run([*ROS2, *args], capture_output=True, text=True, timeout=timeout,
                          cwd=ROOT, env=env)


def test_a_fresh_shell_attaches_to_the_run_going_and_its_printed_lines_paste(tmp_path):
    shell = fresh_shell(tmp_path / "tmp")
    run = subprocess.Popen([*ORCHESTRATE, NAV, "--paused", "--set", "interactive=true", "--out",
                            str(tmp_path / "out")], cwd=ROOT, env=shell, text=True,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        said = []  # what the run says before it waits (warnings first, if any)
        while not said or "ROS domain" not in said[-1]:
            said.append(run.stderr.readline())
            assert said[-1], "".join(said)
        head = said[-1]
        domain = re.search(r"ROS domain (\d+) \(this run's own", head).group(1)
        pasted = [run.stderr.readline().strip() for _ in range(2)]
        env = f"ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID={domain}"
        assert head.rstrip().endswith("its topics from another shell:"), head
        assert re.fullmatch(rf"{env} (\.venv/bin/)?cosim-ros2 topic list", pasted[0]), pasted
        assert pasted[1] == f"{env} ros2 topic list"
        quoted = [re.sub(r"\S*cosim-ros2 ", ".venv/bin/cosim-ros2 ", line.strip()).replace(
            f"ROS domain {domain} ", "ROS domain 42 ").replace(f"_ID={domain} ", "_ID=42 ")
            for line in (f"cosim-orchestrate: {head.split('cosim-orchestrate: ', 1)[1]}",
                         *pasted)]
        for page in ("README.md", "docs/concepts/topics.md"):  # what they quote is so
            lines = [line.strip() for line in (ROOT / page).read_text().splitlines()]
            assert all(line in lines for line in quoted), (page, quoted)

        features = ros2_in(shell, "service", "call", "/get_simulator_features",
                           "simulation_interfaces/srv/GetSimulatorFeatures")
        assert features.returncode == 0, features.stderr
        assert (f"cosim-ros2: attached to ROS domain {domain}, the cosim run going on this "
                f"machine: cosim-orchestrate {NAV}, outputs in {tmp_path / 'out'}"
                ) in features.stderr
        # the printed line as it is, in a shell that could not find the run by itself
        elsewhere = fresh_shell(tmp_path / "elsewhere")
        for _ in range(5):  # a topic list discovers for a second: a loaded machine may need more
            listed = subprocess.run(["bash", "-c", pasted[0]], capture_output=True, text=True,
                                    timeout=60, cwd=ROOT, env=elsewhere)
            if {"/clock", "/odom", "/scan"} <= set(listed.stdout.splitlines()):
                break
        assert {"/clock", "/odom", "/scan"} <= set(listed.stdout.splitlines()), listed.stderr
        assert "attached" not in listed.stderr
        stop = ros2_in(shell, "service", "call", "/set_simulation_state",
                       "simulation_interfaces/srv/SetSimulationState", "{state: {state: 3}}")
        assert stop.returncode == 0, stop.stderr
        code, _, err = finish(run, timeout=60)
    finally:
        interrupt(run)
    assert code in (0, 1), err


def test_with_several_runs_going_it_takes_the_newest_and_names_the_others(tmp_path):
    shell = fresh_shell(tmp_path / "tmp")
    alone = ros2_in(shell, "topic", "list", "--spin-time", "0.2")
    assert alone.returncode == 0 and "cosim-ros2:" not in alone.stderr  # none: domain 0
    holders = []
    try:
        for domain, name in ((230, "run A"), (231, "run B")):  # two runs' claims, held
            holders.append(subprocess.Popen(
                [sys.executable, "-c", "from orchestrator.run_domain import claim; "
                 f"claim({domain}, {name!r}); print('held', flush=True); "
                 "import time; time.sleep(120)"],
                cwd=ROOT, env=shell, stdout=subprocess.PIPE, text=True))
            assert holders[-1].stdout.readline() == "held\n"
            time.sleep(0.05)
        both = ros2_in(shell, "topic", "list", "--spin-time", "0.2")
        assert both.returncode == 0, both.stderr
        assert ("cosim-ros2: 2 cosim runs are going on this machine; attached to the newest, "
                "ROS domain 231: run B (pid") in both.stderr
        assert "The others: ROS domain 230: run A (pid" in both.stderr
        assert "Choose one with --domain ID (or ROS_DOMAIN_ID=ID)" in both.stderr
        for chosen in (ros2_in(shell, "topic", "list", "--spin-time", "0.2", "--domain", "230"),
                       ros2_in({**shell, "ROS_DOMAIN_ID": "230"}, "topic", "list",
                               "--spin-time", "0.2")):
            assert chosen.returncode == 0 and "cosim-ros2:" not in chosen.stderr
    finally:
        for holder in holders:
            holder.kill()
            holder.wait()
    gone = ros2_in(shell, "topic", "list", "--spin-time", "0.2")
    assert "cosim-ros2:" not in gone.stderr  # their claims are no longer held
