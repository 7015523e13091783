"""simulation_interfaces' SpawnEntity and DeleteEntity for objects (issue 49): a plain rclpy
client spawns a box (SDFormat resource_string) in front of the robot and a free cylinder
(URDF), deletes one; every bad request gets its result code and changes nothing; the
requests enter at a tick boundary through the external node, are in the bag, and --replay
gives the run's digest. The parsing of requests is tested on its own, without a run."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from geometry_msgs.msg import PoseStamped
from simulation_interfaces.msg import Resource, Result, SimulationState, SimulatorFeatures
from simulation_interfaces.msg import SpawnEntity as SpawnEntityMsg
from simulation_interfaces.srv import (
    DeleteEntity,
    GetEntities,
    GetSimulatorFeatures,
    GetSpawnables,
    SpawnEntities,
    SpawnEntity,
)

from orchestrator.outputs.bag import BagReader
from orchestrator.ros_surface.spawn_resources import Refused, requested_object
from plan.events import parse_edits
from plan.ros_types import message_class
from tests.helpers import ROOT, replayed_digest
from tests.sim_client import OK, SimClient, live_runs

R = SpawnEntity.Response
TICK_NS = 20_000_000
MESH = ROOT / "scenarios" / "robots" / "mybot_description" / "meshes" / "chassis.stl"
CRATE = """<sdf version="1.9"><model name="crate"><static>true</static><link name="l">
  <collision name="c"><geometry><box><size>0.3 0.3 0.5</size></box></geometry></collision>
  <visual name="v"><geometry><box><size>0.3 0.3 0.5</size></box></geometry>
  <material><diffuse>0.9 0.2 0.1 1</diffuse></material></visual></link></model></sdf>"""
DRUM = """<robot name="drum"><link name="l"><inertial><mass value="2.0"/></inertial>
  <collision><geometry><cylinder radius="0.12" length="0.4"/></geometry></collision>
  </link></robot>"""
ARM = """<robot name="arm"><link name="a"/><link name="b"/>
  <joint name="j" type="revolute"><parent link="a"/><child link="b"/></joint></robot>"""


def request(x: float, y: float, name: str = "", resource: str = "", uri: str = "",
            renaming: bool = False, yaw: float = 0.0, frame: str = "world",
            namespace: str = "") -> SpawnEntity.Request:
    """A SpawnEntity request at (x, y) facing ``yaw``."""
    pose = PoseStamped()
    pose.header.frame_id = frame
    pose.pose.position.x, pose.pose.position.y = float(x), float(y)
    pose.pose.orientation.z, pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return SpawnEntity.Request(name=name, allow_renaming=renaming, uri=uri,
                               resource_string=resource, entity_namespace=namespace,
                               initial_pose=pose)


def test_requests_are_read_as_objects():
    name, box = requested_object(request(1, 2, resource=CRATE, yaw=0.5))
    assert name == "crate" and box.shape == "box" and box.size == (0.3, 0.3, 0.5)
    assert box.static and box.rgba == (0.9, 0.2, 0.1, 1.0)
    assert box.pose.yaw == pytest.approx(0.5) and box.pose.z is None  # on the floor
    name, drum = requested_object(request(0, 0, name="d", resource=DRUM))
    assert name == "d" and drum.shape == "cylinder" and drum.size == (0.12, 0.4)
    assert not drum.static and drum.mass == 2.0
    _, mesh = requested_object(request(0, 0, name="m", uri=f"file://{MESH}"))
    assert mesh.shape == "mesh" and mesh.mesh == str(MESH) and mesh.static
    for bad, code in ((request(0, 0), R.NO_RESOURCE),
                      (request(0, 0, resource="<sdf"), R.RESOURCE_PARSE_ERROR),
                      (request(0, 0, resource=ARM), R.UNSUPPORTED_FORMAT),
                      (request(0, 0, resource="<world/>"), R.UNSUPPORTED_FORMAT),
                      (request(0, 0, uri="/no/such.sdf"), R.NO_RESOURCE),
                      (request(0, 0, uri="package://x/y.urdf"), R.UNSUPPORTED_FORMAT),
                      (request(0, 0, resource=CRATE.replace("0.3 0.3 0.5</size></box></geo"
                                                            "metry></collision>",
                                                            "1</size></box></geometry>"
                                                            "</collision>")),
                       R.RESOURCE_PARSE_ERROR),
                      (request(0, 0, resource=DRUM.replace(
                          '<cylinder radius="0.12" length="0.4"/>',
                          '<mesh filename="meshes/x.stl"/>')), R.MISSING_ASSETS),
                      (request(0, 0, name="bad name", resource=CRATE), R.NAME_INVALID),
                      (request(0, 0, resource=CRATE, frame="laser"), R.INVALID_POSE)):
        with pytest.raises(Refused) as info:
            requested_object(bad)
        assert info.value.code == code, (info.value.code, str(info.value))


def test_the_spawner_checks_requests_against_what_is_in_the_world_then():
    """Without a run: the objects in the world at the next boundary are the scenario's due
    events' and the accepted edits'; a request is checked against them, an accepted one is
    put into the arrivals with every edit so far."""
    from descriptions.load import load_scenario
    from orchestrator.ros_surface.sim_spawn import object_spawner
    from orchestrator.ros_surface.simcontrol import RunControl
    from runtime.arrivals import Arrivals

    scenario = load_scenario(ROOT / "tests" / "scenarios" / "spawn_short.yaml",
                             {"interactive": True})
    control = RunControl(scenario.tick_ns, paused=True)
    arrivals = Arrivals(scenario.nodes["external"].outputs)
    spawner = object_spawner(scenario, control, arrivals)
    control.boundary = 25  # 0.5 s: the ball (0.2 s) and the post (0.4 s) are in
    assert sorted(spawner.live()) == ["ball", "post"]
    on_post = spawner.spawn(request(-2.0, -2.8, name="x", resource=DRUM))
    assert on_post[0] == R.INVALID_POSE and "'post'" in on_post[1], on_post
    renamed = spawner.spawn(request(0.0, 3.0, name="ball", resource=DRUM, renaming=True))
    assert renamed[0] == OK and renamed[2] == "ball_1", renamed
    from plan.obstacles import place_problem

    (post,) = spawner.static_obstacles()  # what a teleport (SetEntityState) is refused in
    assert "inside obstacle 'post'" in place_problem([post], -2.0, -2.8, 0.2)
    assert spawner.delete("post")[0] == OK
    assert spawner.delete("post")[0] == Result.RESULT_NOT_FOUND  # gone at that boundary
    assert spawner.delete("wall_n")[0] == Result.RESULT_OPERATION_FAILED
    (sent,) = arrivals.take().values()
    assert [(e.name, e.delete is not None) for e in parse_edits(sent.data)] == [
        ("ball_1", False), ("post", True)]
    assert [o.name for o in spawner.static_obstacles()] == []  # the drum is free
    control.boundary = 5  # before the events: only the edits
    assert sorted(spawner.live()) == ["ball_1"]


def test_clients_name_only_the_scenarios_spawnables(tmp_path):
    """A file a client names (SpawnEntity's uri, a resource_string's mesh, GetSpawnables'
    sources) is served only from the scenario's spawnables: and their folders; any other
    host path is refused alike whether it exists or not, the message naming the fix."""
    import shutil

    from descriptions.load import load_scenario
    from orchestrator.ros_surface.sim_spawn import object_spawner
    from orchestrator.ros_surface.simcontrol import RunControl
    from orchestrator.ros_surface.spawnables import list_spawnables
    from runtime.arrivals import Arrivals

    scenario = load_scenario(ROOT / "tests" / "scenarios" / "spawn_short.yaml",
                             {"interactive": True, "spawnables": [str(MESH.parent)]})
    control = RunControl(scenario.tick_ns, paused=True)
    spawner = object_spawner(scenario, control, Arrivals(scenario.nodes["external"].outputs))
    control.boundary = 5
    other = tmp_path / "elsewhere.stl"
    shutil.copy(MESH, other)
    assert spawner.spawn(request(0, 3, name="m", uri=f"file://{MESH}"))[0] == OK
    for uri in (str(other), "/etc/hostname", "/no/such.stl", f"file://{MESH.parent}/../x"):
        code, message, _ = spawner.spawn(request(0, 3, name="n", uri=uri))
        assert code == R.NO_RESOURCE and "add it, or its folder, to spawnables:" in message, \
            message
    named = DRUM.replace('<cylinder radius="0.12" length="0.4"/>', f'<mesh filename="{other}"/>')
    code, message, _ = spawner.spawn(request(0, 3, name="n", resource=named))
    assert code == R.MISSING_ASSETS and "spawnables:" in message, message
    found, unknown = list_spawnables(scenario, [str(tmp_path), "/etc", str(MESH.parent)])
    assert found and all(uri.startswith(f"file://{MESH.parent}/") for uri, _ in found)
    assert len(unknown) == 2 and all("spawnables:" in why for why in unknown), unknown


@pytest.fixture(scope="module")
def scenario_file(tmp_path_factory):
    """spawn_short without its events and camera, interactive, 2 s."""
    doc = yaml.safe_load((ROOT / "tests" / "scenarios" / "spawn_short.yaml").read_text())
    doc["world"] = str(ROOT / "scenarios" / "worlds" / "nav.xml")
    doc.pop("events")
    doc["duration"] = "2s"
    doc["interactive"] = True
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] != "camera"]
    doc["spawnables"] = [str(ROOT / "scenarios" / "robots" / "usd"),
                         {"path": str(ROOT / "scenarios" / "worlds" / "robot.xml"),
                          "description": "the nav robot"}]
    path = tmp_path_factory.mktemp("spawn") / "spawn_live.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def session(sim: SimClient, checks: bool) -> int:
    """Spawn, refuse, list, delete, all while paused; returns the tick it stopped before."""
    assert sim.step(10).result == OK
    features = sim.call(GetSimulatorFeatures, "/get_simulator_features",
                        GetSimulatorFeatures.Request()).features
    spawnables = sim.call(GetSpawnables, "/get_spawnables",
                          GetSpawnables.Request(sources=["/no/such/folder"]))

    def spawn(req):
        return sim.call(SpawnEntity, "/spawn_entity", req)

    def delete(name):
        return sim.call(DeleteEntity, "/delete_entity", DeleteEntity.Request(entity=name)).result

    crate = spawn(request(-2.2, -2.2, resource=CRATE))  # 1.1 m ahead of the robot
    drum = spawn(request(-2.0, -2.8, name="crate", resource=DRUM, renaming=True))
    refused = {
        "taken": spawn(request(-1, -3.5, name="crate", resource=DRUM)).result,
        "world's": spawn(request(-1, -3.5, name="pillar_a", resource=DRUM)).result,
        "obstacle": spawn(request(1.6, 2.6, name="x", resource=DRUM)).result,
        "robot": spawn(request(-3.0, -2.95, name="x", resource=DRUM)).result,
        "robot description": spawn(request(0, 3, resource=ARM)).result,
        "namespace": spawn(request(0, 3, resource=DRUM, namespace="/r1")).result,
        "no file": spawn(request(0, 3, uri="/no/such.stl")).result,
        "wall": delete("wall_n"),
        "ghost": delete("ghost"),
    }
    many = SpawnEntities.Request()
    for req in (request(0.5, -3.5, name="drum2", resource=DRUM),
                request(1.6, 2.6, name="y", resource=DRUM)):  # pillar_a
        many.spawn_requests.append(SpawnEntityMsg(
            name=req.name, initial_pose=req.initial_pose,
            entity_resource=Resource(resource_string=req.resource_string)))
    both = sim.call(SpawnEntities, "/spawn_entities", many)
    entities = sim.call(GetEntities, "/get_entities", GetEntities.Request()).entities
    assert sim.step(20).result == OK
    deleted = delete("crate_1")
    assert sim.step(20).result == OK
    stop = sim.set_state(SimulationState.STATE_STOPPED)
    if checks:
        assert {SimulatorFeatures.SPAWNING, SimulatorFeatures.DELETING,
                SimulatorFeatures.SPAWNING_RESOURCE_STRING,
                SimulatorFeatures.SPAWNING_ENTITIES} <= set(features.features)
        assert "sdf" in features.spawn_formats and "urdf" in features.spawn_formats
        assert SimulatorFeatures.SPAWNABLES in features.features
        listed = {s.uri: s.description for s in spawnables.spawnables}
        folder = sorted(f for f in (ROOT / "scenarios" / "robots" / "usd").iterdir()
                        if f.suffix in (".urdf", ".xacro", ".usd", ".usda", ".xml"))
        assert [f"file://{f}" for f in folder] == list(listed)[:len(folder)]
        assert listed[f"file://{ROOT / 'scenarios' / 'worlds' / 'robot.xml'}"] == "the nav robot"
        assert spawnables.result.result == Result.RESULT_NOT_FOUND  # not a spawnable
        assert "/no/such/folder" in spawnables.result.error_message
        assert crate.result.result == OK and crate.entity_name == "crate", crate.result
        assert "tick 10" in crate.result.error_message
        assert drum.result.result == OK and drum.entity_name == "crate_1", drum.result
        codes = {k: r.result for k, r in refused.items()}
        assert codes == {"taken": R.NAME_NOT_UNIQUE, "world's": R.NAME_NOT_UNIQUE,
                         "obstacle": R.INVALID_POSE, "robot": R.INVALID_POSE,
                         "robot description": R.UNSUPPORTED_FORMAT,
                         "namespace": R.NAMESPACE_INVALID, "no file": R.NO_RESOURCE,
                         "wall": Result.RESULT_OPERATION_FAILED,
                         "ghost": Result.RESULT_NOT_FOUND}, {k: r.error_message
                                                             for k, r in refused.items()}
        assert "pillar_a" in refused["obstacle"].error_message
        assert both.result.result == SpawnEntities.Response.ENTITIES_SPAWN_FAILED
        assert [r.result.result for r in both.results] == [OK, R.INVALID_POSE]
        assert both.results[0].entity_name == "drum2"
        assert list(entities) == ["base_link", "crate", "crate_1", "drum2"]
        assert deleted.result == OK, deleted.error_message
        assert stop.result == OK, stop.error_message
    return int(stop.error_message.split("before tick ")[1].split()[0])


def test_clients_spawn_and_delete_objects_recorded_and_replayed(tmp_path, ros_node,
                                                                 scenario_file):
    (run,) = live_runs(ros_node, scenario_file, tmp_path, session, times=1)
    assert run.returncode == 0, run.stderr  # stopped: no goal to reach in this scenario
    with BagReader(run.run_dir / "bag") as bag:
        edits = {s // TICK_NS: m.data for s, m in bag.messages(
            "/cosim/world_edits", message_class("std_msgs/msg/String"))}
        states = {s // TICK_NS: m for s, m in bag.messages(
            "/cosim/world_state", message_class("std_msgs/msg/Float64MultiArray"))}
        scans = {s // TICK_NS: np.frombuffer(m.ranges, dtype=np.float32) for s, m in
                 bag.messages("/scan", message_class("sensor_msgs/msg/LaserScan"))}
    assert edits[9] == "" and [e.name for e in parse_edits(edits[10])] == [
        "crate", "crate_1", "drum2"]
    assert [e.delete for e in parse_edits(edits[30])] == [None, None, None, "crate_1"]
    assert states[9].layout.dim[0].size == 11 and states[10].layout.dim[0].size == 25
    assert states[30].layout.dim[0].size == 18  # one free drum taken out at tick 30
    ahead = slice(41, 47)
    assert scans[5][ahead].min() > 3.5 and scans[10][ahead].min() < 1.0  # the crate
    # --replay from the run directory alone, in-process: the recorded requests, one digest
    assert replayed_digest(run.run_dir, tmp_path / "replay") == run.digest
