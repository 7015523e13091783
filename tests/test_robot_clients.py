"""Robots a client brings into a running swarm and takes out (issue 49): SpawnEntity of a
robot description the scenario's ``spawnables:`` plans robots of (tests/scenarios/
swarm_clients.yaml: mybot_0 and mybot_1, each with its goal). A plain rclpy client brings
both in and a USD one, a fourth is refused (no planned robot left), takes one out; one
drives to its goal; each enters at a
tick boundary with its lidar and controller (dormant until then), its topics appear, the
requests are in the bag and ``--replay`` in-process gives the run's digest."""

from __future__ import annotations

import json
import math
import subprocess

import pytest
from geometry_msgs.msg import PoseStamped
from simulation_interfaces.msg import Result
from simulation_interfaces.srv import DeleteEntity, SpawnEntity

from orchestrator.outputs.bag import BagReader
from plan.ros_types import message_class
from tests.helpers import ORCHESTRATE, ROOT
from tests.sim_client import OK, SimClient, live_runs

SCENARIO = ROOT / "tests" / "scenarios" / "swarm_clients.yaml"
MYBOT = ROOT / "scenarios" / "robots" / "mybot_description" / "urdf" / "mybot.urdf.xacro"
USDBOT = ROOT / "scenarios" / "robots" / "usd" / "mybot_isaac.usda"
TICK_NS = 20_000_000


def bring(sim: SimClient, x: float, y: float, yaw: float = 0.0, name: str = "",
          file=MYBOT):
    """SpawnEntity of a planned robot's description at (x, y) facing ``yaw``."""
    pose = PoseStamped()
    pose.header.frame_id = "world"
    pose.pose.position.x, pose.pose.position.y = x, y
    pose.pose.orientation.z, pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return sim.call(SpawnEntity, "/spawn_entity", SpawnEntity.Request(
        name=name, uri=f"file://{file}", initial_pose=pose))


def session(sim: SimClient, checks: bool) -> int:
    """Two URDF robots and a USD one in at tick 10, a fourth refused, one out at tick 40;
    stop before 50."""
    assert sim.step(10).result == OK
    first = bring(sim, -2.5, 0.0)
    inside = bring(sim, 1.3, 1.3)  # a pillar: refused, mybot_1 stays free
    second = bring(sim, 2.0, 2.0, -1.5708)
    usd = bring(sim, 0.0, 3.0, -1.5708, file=USDBOT)
    third = bring(sim, 2.0, -2.0)  # none left
    assert sim.step(30).result == OK
    gone = sim.call(DeleteEntity, "/delete_entity", DeleteEntity.Request(entity="mybot_1"))
    again = sim.call(DeleteEntity, "/delete_entity", DeleteEntity.Request(entity="mybot_1"))
    assert sim.step(10).result == OK
    stop = sim.set_state(3)  # SimulationState.STATE_STOPPED
    if checks:
        assert (first.result.result, first.entity_name) == (OK, "mybot_0"), first.result
        assert (second.result.result, second.entity_name) == (OK, "mybot_1")
        assert (usd.result.result, usd.entity_name) == (OK, "usdbot"), usd.result
        assert third.result.result == Result.RESULT_OPERATION_FAILED
        assert "plans 2 (mybot_0, mybot_1), all taken" in third.result.error_message
        assert inside.result.result == SpawnEntity.Response.INVALID_POSE
        assert gone.result.result == OK and again.result.result == Result.RESULT_NOT_FOUND
        assert stop.result == OK
    return int(stop.error_message.split("before tick ")[1].split()[0])


def test_clients_bring_robots_in_and_take_them_out(tmp_path, ros_node):
    (run,) = live_runs(ros_node, SCENARIO, tmp_path, session, times=1)
    assert run.returncode == 0, run.stderr
    odom = message_class("nav_msgs/msg/Odometry")
    with BagReader(run.run_dir / "bag") as bag:
        first = [s // TICK_NS for s, _ in bag.messages("/mybot_0/odom", odom)]
        second = [s // TICK_NS for s, _ in bag.messages("/mybot_1/odom", odom)]
        scans = [s // TICK_NS for s, _ in bag.messages(
            "/mybot_0/scan", message_class("sensor_msgs/msg/LaserScan"))]
    assert first[0] == 10 and first[-1] == run.stopped_at - 1  # in from the tick it entered
    assert second[0] == 10 and second[-1] == 39  # out at tick 40: quiet from then on
    assert scans[0] == 10  # its lidar, dormant until then
    metrics = json.loads((run.run_dir / "manifest.json").read_text())["outcome"]["metrics"]
    assert metrics["mybot_0/arrived"] == 1.0, metrics  # its controller drove it to its goal
    assert metrics["usdbot/x"] == pytest.approx(0.0, abs=0.3)
    again = subprocess.run([*ORCHESTRATE, "--replay", str(run.run_dir), "--in-process",
                            "--quiet", "--out", str(tmp_path / "replay")],
                           capture_output=True, text=True, timeout=240, cwd=ROOT)
    assert again.returncode == 0 and run.digest in again.stdout, again.stderr
    (replay_dir,) = (tmp_path / "replay").iterdir()
    assert json.loads((replay_dir / "manifest.json").read_text())["digest"] == run.digest
