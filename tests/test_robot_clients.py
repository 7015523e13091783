"""Robots a client brings into a running swarm and takes out (issue 49): SpawnEntity of a
robot description the scenario's ``spawnables:`` plans robots of (tests/scenarios/
swarm_clients.yaml: mybot_0..3 of a URDF (xacro) and usdbot_0..3 of a USD file, each with
its goal). A plain rclpy client brings all eight in (one request in a pillar refused, a
ninth refused: no planned robot left) and takes two out; the six that stay drive to their
goals; each enters at a tick boundary with its lidar and controller (dormant until then),
its topics appear, the requests are in the bag and ``--replay`` in-process gives the run's
digest."""

from __future__ import annotations

import json
import math

from geometry_msgs.msg import PoseStamped
from simulation_interfaces.msg import Result
from simulation_interfaces.srv import DeleteEntity, SpawnEntity

from orchestrator.outputs.bag import BagReader
from plan.ros_types import message_class
from tests.helpers import ROOT, replayed_digest
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


URDF = {"mybot_0": (-2.5, 0.0, 0.0), "mybot_1": (2.0, 2.0, -1.5708),
        "mybot_2": (-3.0, 3.0, 0.0), "mybot_3": (3.0, 3.0, 3.1416)}
USD = {"usdbot_0": (0.0, 3.0, -1.5708), "usdbot_1": (-3.0, -3.0, 0.0),
       "usdbot_2": (3.0, -3.0, 3.1416), "usdbot_3": (-3.0, 1.5, 0.0)}
TAKEN_OUT = ("mybot_1", "usdbot_3")  # at tick 40


def session(sim: SimClient, checks: bool) -> int:
    """Four URDF robots and four USD ones in at tick 10 (a request in a pillar and a ninth
    refused), two out at tick 40; stop before 50."""
    assert sim.step(10).result == OK
    inside = bring(sim, 1.3, 1.3)  # a pillar: refused, every robot stays free
    brought = {name: bring(sim, *URDF[name]) for name in URDF}
    brought |= {name: bring(sim, *USD[name], file=USDBOT) for name in USD}
    ninth = bring(sim, 2.0, -2.0)  # none left
    assert sim.step(30).result == OK
    gone = [sim.call(DeleteEntity, "/delete_entity", DeleteEntity.Request(entity=name))
            for name in TAKEN_OUT]
    again = sim.call(DeleteEntity, "/delete_entity", DeleteEntity.Request(entity="mybot_1"))
    assert sim.step(10).result == OK
    stop = sim.set_state(3)  # SimulationState.STATE_STOPPED
    if checks:
        assert {n: (r.result.result, r.entity_name) for n, r in brought.items()} == {
            n: (OK, n) for n in brought}, {n: r.result.error_message for n, r in brought.items()}
        assert ninth.result.result == Result.RESULT_OPERATION_FAILED
        assert "plans 4 (mybot_0, mybot_1, mybot_2, mybot_3), all taken" in \
            ninth.result.error_message
        assert inside.result.result == SpawnEntity.Response.INVALID_POSE
        assert [r.result.result for r in gone] == [OK, OK]
        assert again.result.result == Result.RESULT_NOT_FOUND
        assert stop.result == OK
    return int(stop.error_message.split("before tick ")[1].split()[0])


def test_clients_bring_robots_in_and_take_them_out(tmp_path, ros_node):
    (run,) = live_runs(ros_node, SCENARIO, tmp_path, session, times=1)
    assert run.returncode == 0, run.stderr
    odom = message_class("nav_msgs/msg/Odometry")
    with BagReader(run.run_dir / "bag") as bag:
        ticks = {name: [s // TICK_NS for s, _ in bag.messages(f"/{name}/odom", odom)]
                 for name in [*URDF, *USD]}
        scans = [s // TICK_NS for s, _ in bag.messages(
            "/usdbot_0/scan", message_class("sensor_msgs/msg/LaserScan"))]
        edits = [s // TICK_NS for s, _ in bag.messages(
            "/cosim/world_edits", message_class("std_msgs/msg/String"))]
    for name, seen in ticks.items():  # in from the tick it entered, out at tick 40
        assert (seen[0], seen[-1]) == (10, 39 if name in TAKEN_OUT else run.stopped_at - 1)
    assert scans[0] == 10  # its lidar, dormant until then
    assert 10 in edits and 40 in edits  # the requests, recorded
    metrics = json.loads((run.run_dir / "manifest.json").read_text())["outcome"]["metrics"]
    arrived = {n: metrics[f"{n}/arrived"] for n in ticks if n not in TAKEN_OUT}
    assert arrived == dict.fromkeys(arrived, 1.0), metrics  # driven to their goals
    assert replayed_digest(run.run_dir, tmp_path / "replay") == run.digest
