"""ROS 2 clients drive an interactive nav run (multi-process, no camera): entity state and a
teleport, a parameter change, NavigateToPose goals (one reached, one cancelled), a stop.
Everything is sent while the run is paused, so it enters at a known tick: two runs give one
digest, and the in-process run fed what the bag recorded gives it too."""

from __future__ import annotations

import json
import math
import subprocess

import pytest
import yaml
from nav2_msgs.action import NavigateToPose
from simulation_interfaces.msg import SimulationState, SimulatorFeatures
from simulation_interfaces.srv import (
    GetEntities,
    GetEntityState,
    GetSimulatorFeatures,
    SetEntityState,
)

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from orchestrator.outputs.bag import BagReader
from plan.ros_types import message_class
from tests.helpers import ORCHESTRATE, ROOT
from tests.sim_client import OK, SimClient, live_runs

NAV = ROOT / "scenarios" / "nav.yaml"
TICK_NS = 20_000_000
SUCCEEDED, CANCELED, ABORTED = 4, 5, 6  # action_msgs/GoalStatus
TELEPORT = (-3.3, -3.0, math.pi / 2)
NEAR = (-3.3, -1.6, math.pi / 2)  # straight ahead of the teleported robot, 1.4 m
FAR = (3.0, 3.0, 0.0)


@pytest.fixture(scope="module")
def scenario_file(tmp_path_factory):
    """nav without the camera, interactive, no stop at the goal (the client stops it)."""
    doc = yaml.safe_load(NAV.read_text())
    doc["world"] = str((NAV.parent / doc["world"]).resolve())
    doc["duration"] = "40s"
    doc["interactive"] = True
    doc["success"]["stop_on_goal"] = False
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] != "camera"]
    path = tmp_path_factory.mktemp("nav") / "nav_interactive.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def nav_goal(x: float, y: float, yaw: float, frame: str = "map") -> NavigateToPose.Goal:
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = frame
    goal.pose.pose.position.x, goal.pose.pose.position.y = x, y
    goal.pose.pose.orientation.z, goal.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(
        yaw / 2)
    return goal


def session(sim: SimClient, checks: bool) -> int:
    """The client's session, all while paused; ``checks``: assert what the replies say.
    Returns the tick the run was stopped before."""
    assert sim.step(10).result == OK
    features = sim.call(GetSimulatorFeatures, "/get_simulator_features",
                        GetSimulatorFeatures.Request()).features.features
    entities = sim.call(GetEntities, "/get_entities", GetEntities.Request()).entities
    state = sim.call(GetEntityState, "/get_entity_state",
                     GetEntityState.Request(entity="base_link"))
    if checks:
        assert {SimulatorFeatures.ENTITY_STATE_GETTING,
                SimulatorFeatures.ENTITY_STATE_SETTING} <= set(features)
        assert list(entities) == ["base_link"]
        assert state.result.result == OK
        p = state.state.pose.position  # the start, a few cm on after 9 ticks
        assert math.hypot(p.x + 3.0, p.y + 3.0) < 0.1 and state.state.header.frame_id == "world"

    # parameters: checked like the scenario; a good one enters at tick 10
    bad = sim.set_param("control", "max_speed", -1.0)
    fixed = sim.set_param("control", "resolution", 0.1)
    good = sim.set_param("control", "max_speed", 0.3)
    if checks:
        assert not bad.successful and "greater than 0" in bad.reason, bad.reason
        assert not fixed.successful and "read-only" in fixed.reason, fixed.reason
        assert good.successful, good.reason
        assert sim.get_param("control", "max_speed") == 0.3

    # teleport: refused inside an obstacle, else applied at tick 10
    request = SetEntityState.Request(entity="base_link")
    request.state.pose.position.x, request.state.pose.position.y = -1.5, -2.6  # box_a
    request.state.pose.orientation.w = 1.0
    inside = sim.call(SetEntityState, "/set_entity_state", request).result
    x, y, yaw = TELEPORT
    request.state.pose.position.x, request.state.pose.position.y = x, y
    request.state.pose.orientation.z = math.sin(yaw / 2)
    request.state.pose.orientation.w = math.cos(yaw / 2)
    moved = sim.call(SetEntityState, "/set_entity_state", request).result
    if checks:
        assert inside.result == SetEntityState.Response.INVALID_POSE, inside.error_message
        assert "box_a" in inside.error_message
        assert moved.result == OK, moved.error_message

    # NavigateToPose: a frame cosim does not have is refused; a goal is reached
    wrong = sim.send_goal(NavigateToPose, "/navigate_to_pose", nav_goal(*NEAR, frame="laser"))
    near = sim.send_goal(NavigateToPose, "/navigate_to_pose", nav_goal(*NEAR))
    for _ in range(8):
        assert sim.step(50).result == OK
    reached = sim.result(near)
    sim.spin_until(lambda: len(near.feedback) >= 1)
    if checks:
        refused = sim.result(wrong)
        assert refused.status == ABORTED and refused.result.error_code == 9002
        assert reached.status == SUCCEEDED, reached.result.error_msg
        fb = near.feedback
        times = [f.navigation_time.sec * 10**9 + f.navigation_time.nanosec for f in fb]
        assert times[0] == 0 and all(t % 100_000_000 == 0 for t in times)  # control ticks
        assert times == sorted(set(times)) and len(times) > 30
        assert fb[0].distance_remaining > 1.2 > 0.3 > fb[-1].distance_remaining
        assert all(f.number_of_recoveries == 0 for f in fb)
        # Nav2's estimate: distance left over speed, zero until the robot moves
        etas = [f.estimated_time_remaining.sec + f.estimated_time_remaining.nanosec / 1e9
                for f in fb]
        moving = [(eta, f.distance_remaining) for eta, f in zip(etas, fb, strict=True)
                  if eta > 0]
        assert etas[0] == 0.0 and len(moving) > len(fb) // 2, etas
        assert all(eta >= left / 0.35 for eta, left in moving), moving  # at most ~0.3 m/s
        assert fb[-1].current_pose.header.frame_id == "odom"
        assert math.hypot(fb[-1].current_pose.pose.position.x - NEAR[0],
                          fb[-1].current_pose.pose.position.y - NEAR[1]) < 0.25

    # a new goal after reaching one is taken; cancelled, the robot stops
    far = sim.send_goal(NavigateToPose, "/navigate_to_pose", nav_goal(*FAR))
    assert sim.step(50).result == OK
    sim.spin_until(lambda: len(far.feedback) == 10)  # control ticks 420, 425, ... 465
    sim.cancel(far)
    assert sim.step(20).result == OK
    cancelled = sim.result(far)
    stop = sim.set_state(SimulationState.STATE_STOPPED)
    if checks:
        assert cancelled.status == CANCELED, cancelled.result.error_msg
        assert stop.result == OK, stop.error_message
    return int(stop.error_message.split("before tick ")[1].split()[0])


def recorded_inputs(run_dir, scenario) -> dict[int, dict]:
    """What the external node published at each tick, from the bag: a replay of the run's
    arrivals (the node holds the latest message; feeding it again changes nothing)."""
    topics = scenario.nodes["external"].outputs
    inputs: dict[int, dict] = {}
    with BagReader(run_dir / "bag") as bag:
        for topic in topics:
            for stamp, msg in bag.messages(topic, message_class(bag.msgtype(topic))):
                if _arrived(msg):
                    inputs.setdefault(stamp // TICK_NS, {})[topic] = msg
    return inputs


def _arrived(msg) -> bool:
    """Whether an external message is a client's, not the default one held before."""
    if hasattr(msg, "header"):  # /goal_pose
        return bool(msg.header.frame_id)
    if hasattr(msg, "data"):  # /cosim/world_edits
        return bool(msg.data)
    return bool(msg.name if hasattr(msg, "name") else msg.node)  # teleport, parameters


def test_clients_drive_the_run_reproducibly(tmp_path, ros_node, scenario_file):
    runs = live_runs(ros_node, scenario_file, tmp_path, session)
    for run in runs:
        assert run.returncode == 1, run.stderr  # stopped with no goal left: goal not met
    assert runs[0].digest == runs[1].digest  # the same requests at the same ticks: one run

    run_dir, digest, stopped_at = runs[0].run_dir, runs[0].digest, runs[0].stopped_at
    scenario = load_scenario(scenario_file, {"duration": f"{(stopped_at - 1) * 20}ms"})
    inputs = recorded_inputs(run_dir, scenario)
    assert sorted(inputs)[0] == 10  # paused at tick 10: everything entered at tick 10
    assert set(inputs[10]) == {"/goal_pose", "/cosim/set_pose", "/cosim/params/control"}
    replayed = run_in_process(scenario, external=lambda k: inputs.get(k, {}))
    assert replayed.digest == digest
    # --replay from the run directory alone (the scenario it names, the arrivals it recorded:
    # goal, teleport, parameter set), in-process: the recorded digest, or exit 4
    again = subprocess.run([*ORCHESTRATE, "--replay", str(run_dir), "--in-process", "--quiet",
                            "--out", str(tmp_path / "replay")], capture_output=True, text=True,
                           timeout=240, cwd=ROOT)
    assert again.returncode == 1 and digest in again.stdout, again.stderr  # goal not met
    (replay_dir,) = (tmp_path / "replay").iterdir()
    assert json.loads((replay_dir / "manifest.json").read_text())["ticks"] == stopped_at

    with BagReader(run_dir / "bag") as bag:
        odom = {s // TICK_NS: m for s, m in bag.messages("/odom", message_class(
            "nav_msgs/msg/Odometry"))}
        cmd = {s // TICK_NS: (m.linear.x, m.angular.z) for s, m in bag.messages(
            "/cmd_vel", message_class("geometry_msgs/msg/Twist"))}
        goals = {s // TICK_NS: m for s, m in bag.messages("/goal_pose", message_class(
            "geometry_msgs/msg/PoseStamped"))}
    p = odom[10].pose.pose.position
    assert (p.x, p.y) == TELEPORT[:2]  # the state published at tick 10 is the teleported one
    assert max(v for k, (v, _) in cmd.items() if k >= 10) == pytest.approx(0.3)  # new limit
    stopped = min(k for k, g in goals.items() if g.header.frame_id and not (
        g.pose.orientation.z or g.pose.orientation.w))
    assert any(cmd[k] != (0.0, 0.0) for k in cmd if 420 <= k < stopped)
    assert all(cmd[k] == (0.0, 0.0) for k in cmd if k >= stopped)  # cancelled: it stops

    # the parameter change is what kept the robot at 0.3 m/s: without it, it goes faster
    unchanged = {k: {t: m for t, m in v.items() if t != "/cosim/params/control"}
                 for k, v in inputs.items()}
    cmd_without: dict[int, float] = {}
    other = run_in_process(scenario, _collect(cmd_without),
                           external=lambda k: unchanged.get(k, {}))
    assert other.digest != digest
    assert max(v for k, v in cmd_without.items() if k >= 10) > 0.35


def _collect(into: dict):
    """An in-process observer that keeps /cmd_vel's linear.x per tick."""
    from geometry_msgs.msg import Twist

    from runtime.cdr.decode import decode

    def observe(tick, node, items):
        for topic, data in items:
            if topic == "/cmd_vel":
                into[tick] = decode(data, Twist).linear.x
    return observe

