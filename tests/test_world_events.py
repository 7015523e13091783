"""Objects that enter and leave a running world (a scenario's ``events:``, issue 49).

A box put in front of the nav robot at 5 s is seen by its lidar and driven around; a short
run with a free ball spawned, a static post spawned, the ball deleted and a mesh spawned
gives one digest
in-process and multi-process, its world state naming the version (and qpos layout) of the
world it shows; MjSpec.recompile keeps every other body's state bit for bit; bad events are
refused at load time naming the key.
"""

from __future__ import annotations

import math
import textwrap

import mujoco
import numpy as np
import pytest

from descriptions.load import load_scenario
from nodes.physics.messages import world_version
from nodes.physics.world_events import LiveWorld, model_at
from nodes.sensors.mirror import WorldMirror
from orchestrator.api import run
from plan.errors import ScenarioError
from plan.events import EventSpec, edit_event
from tests.helpers import ROOT, orchestrate

SCENARIOS = ROOT / "tests" / "scenarios"
NAV_WORLD = ROOT / "scenarios" / "worlds" / "nav.xml"
S = 1_000_000_000


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    """spawn_short in-process: ball at 0.2 s, post at 0.4 s, ball deleted at 0.6 s."""
    result = run(SCENARIOS / "spawn_short.yaml", in_process=True,
                 out=tmp_path_factory.mktemp("runs"), picture=False)
    assert result.success, result.error
    return result


def test_a_box_spawned_in_front_of_the_nav_robot_is_driven_around(tmp_path):
    box = np.array([-0.3, -2.05])
    result = run(SCENARIOS / "nav_spawn.yaml", in_process=True, out=tmp_path, picture=False)
    assert result.success, result.error
    assert result.metrics["collisions"] == 0
    assert result.metrics["goal_reached"] == 1.0
    plans = [(t, p) for t, p in result.messages("/plan") if p.poses]
    before = [p for t, p in plans if t < 5 * S][-1]
    way = np.array([[q.pose.position.x, q.pose.position.y] for q in before.poses])
    assert np.hypot(*(way - box).T).min() < 0.2  # the box stands on the planned way
    odom = dict(result.messages("/odom"))
    assert min(math.hypot(o.pose.pose.position.x - box[0], o.pose.pose.position.y - box[1])
               for o in odom.values()) > 0.35  # never through it
    scans = dict(result.messages("/scan"))

    def towards_box(t: int) -> tuple[float, float]:
        """(the lidar's range towards the box's centre, the distance to it) at time t."""
        p, q = odom[t].pose.pose.position, odom[t].pose.pose.orientation
        bearing = math.atan2(box[1] - p.y, box[0] - p.x) - 2 * math.atan2(q.z, q.w)
        scan = scans[t]
        ranges = np.frombuffer(scan.ranges, dtype=np.float32)
        i = round(((bearing - scan.angle_min) % (2 * math.pi)) / scan.angle_increment)
        return float(ranges[i % len(ranges)]), math.hypot(box[0] - p.x, box[1] - p.y)

    seen, distance = towards_box(4_900_000_000)
    assert seen > distance + 0.5  # nothing there yet
    seen, distance = towards_box(5 * S)
    # the box's near side, from the lidar ahead of the base's centre
    assert distance - 0.45 < seen < distance - 0.1


def test_spawn_and_delete_one_digest_in_process_and_multi_process(short_run, tmp_path):
    versions = {t: (world_version(m)[0], m.layout.dim[0].size)
                for t, m in short_run.messages("/cosim/world_state")}
    assert versions[180_000_000] == (0, 11)  # the robot: 7 + 2 wheels + pan + tilt
    assert versions[200_000_000] == (1, 18)  # and the free ball
    assert versions[400_000_000] == (2, 18)  # and the static post (no joint)
    assert versions[600_000_000] == (3, 11)  # the ball taken out
    assert versions[800_000_000] == (4, 11)  # and a static mesh put in
    cli = orchestrate(SCENARIOS / "spawn_short.yaml", tmp_path)
    assert cli.code == 0, cli.stderr
    assert cli.manifest["digest"] == short_run.digest


def test_the_lidar_sees_what_physics_has(short_run):
    scans = {t: np.frombuffer(m.ranges, dtype=np.float32)
             for t, m in short_run.messages("/scan")}
    ahead = slice(41, 47)  # the robot faces the ball (1.1 m ahead)
    assert scans[300_000_000][ahead].min() > 3.5  # falling, still above the scan plane
    assert scans[400_000_000][ahead].min() == pytest.approx(0.75, abs=0.1)  # on the floor
    assert scans[600_000_000][ahead].min() > 3.5  # deleted


def test_the_camera_sees_the_world_change(short_run):
    """The objects' blue (the default rgba) is in the picture while they are in the world
    and in view: the ball in the air and on the floor, nothing once it is deleted (the
    post is out of view), the mesh (a new GL context for it)."""
    blue = {}
    for t, m in short_run.messages("/camera/color/image_raw"):
        rgb = np.frombuffer(m.data, dtype=np.uint8).reshape(m.height, m.width, 3).astype(int)
        blue[t] = int(((rgb[..., 2] > rgb[..., 0] + 40) & (rgb[..., 2] > rgb[..., 1] + 10)).sum())
    assert blue[0] == 0 and blue[600_000_000] == 0
    assert blue[200_000_000] > 20 and blue[400_000_000] > 20
    assert blue[800_000_000] > 200


def test_recompiling_keeps_every_other_body_state_bit_for_bit():
    events = tuple(EventSpec.model_validate(e) for e in (
        {"at": "20ms", "spawn": {"name": "ball", "shape": "sphere", "size": [0.1],
                                 "pose": {"x": 1, "y": 1}, "static": False, "mass": 1.0}},
        {"at": "40ms", "delete": "ball"}))
    live = LiveWorld(NAV_WORLD, None, events)
    model = live.model
    data = mujoco.MjData(model)
    data.ctrl[:] = 0.5
    for _ in range(30):
        mujoco.mj_step(model, data)
    state = {k: getattr(data, k).copy() for k in ("qpos", "qvel", "act", "ctrl",
                                                  "qacc_warmstart")}
    model2, data2 = live.advance(data, 20_000_000)
    assert live.version == 1 and model2.nq == model.nq + 7
    for key, value in state.items():
        assert np.array_equal(getattr(data2, key)[:len(value)], value), key
    assert data2.time == data.time
    assert live.advance(data2, 30_000_000) is None
    model3, data3 = live.advance(data2, 40_000_000)
    assert model3.nq == model.nq
    assert np.array_equal(data3.qpos, state["qpos"]) and np.array_equal(data3.qvel,
                                                                        state["qvel"])


def test_clients_edits_between_events_are_mirrored_and_bad_ones_change_nothing():
    """A client's edit applied before a scenario event: world states name the sequence, and
    a mirror built from it has the physics node's layout; an edit the world cannot take
    (a name it has, a delete of nothing) is noted and changes nothing."""
    event = EventSpec.model_validate({"at": "40ms", "spawn": {
        "name": "post", "shape": "cylinder", "size": [0.1, 0.5], "pose": {"x": 2, "y": -3}}})
    notes = []
    live = LiveWorld(NAV_WORLD, None, (event,), notes.append)
    data = mujoco.MjData(live.model)
    ball = edit_event({"spawn": {"name": "ball", "shape": "sphere", "size": [0.1],
                                 "pose": {"x": 1, "y": 1}, "static": False, "mass": 1.0}})
    clash = edit_event({"spawn": {"name": "floor", "shape": "sphere", "size": [0.1],
                                  "pose": {"x": 1, "y": 2}}})
    ghost = edit_event({"delete": "ghost"})
    model, data = live.advance(data, 20_000_000, [ball, clash, ghost])
    assert live.advance(data, 20_000_000, [ball, clash, ghost]) is None  # each applies once
    model, data = live.advance(data, 40_000_000, [ball, clash, ghost])
    assert [n.split(":")[0] for n in notes] == ["client edit 2", "client edit 3"]
    assert live.version == 2 and live.label
    mirrored = model_at(str(NAV_WORLD), None, (event,), live.version, live.label)
    assert mirrored.nq == model.nq == 18
    assert [mirrored.body(b).name for b in range(mirrored.nbody)] == [
        model.body(b).name for b in range(model.nbody)]
    assert [model.body(b).name for b in range(model.nbody)][-2:] == ["ball", "post"]


def test_a_shared_mirror_follows_the_version_each_input_shows(short_run):
    scenario = load_scenario(SCENARIOS / "spawn_short.yaml")
    mirror = WorldMirror(scenario.world, None, tuple(scenario.model.events))
    states = dict(short_run.messages("/cosim/world_state"))
    for t in (400_000_000, 200_000_000, 600_000_000, 0):  # a node may trail another
        mirror.update(states[t])
        assert mirror.version == world_version(states[t])[0]
        assert mirror.model.nq == states[t].layout.dim[0].size
    stranger = WorldMirror(scenario.world)  # knows no events
    with pytest.raises(ValueError, match="1 events applied; this node knows 0"):
        stranger.update(states[200_000_000])


def test_a_swarm_robots_lidar_sees_an_object_spawned_before_it(tmp_path):
    """In a swarm each lidar casts against the arena without robots (StaticWorld): that
    arena gets the spawned object too, at the version the world state names."""
    import yaml

    doc = yaml.safe_load((SCENARIOS / "swarm_small.yaml").read_text())
    doc["world"] = str(ROOT / "scenarios" / "worlds" / "arena.xml")
    doc["robots"]["description"] = str(ROOT / "scenarios" / "worlds" / "robot.xml")
    doc["duration"] = "300ms"
    path = tmp_path / "swarm.yaml"
    path.write_text(yaml.safe_dump(doc))
    x, y, yaw = load_scenario(path).robots.robots[0].start
    ahead = (x + 0.8 * math.cos(yaw), y + 0.8 * math.sin(yaw))
    doc["events"] = [{"at": "200ms", "spawn": {"name": "post", "shape": "cylinder",
                                               "size": [0.1, 1.0],
                                               "pose": {"x": ahead[0], "y": ahead[1]}}}]
    path.write_text(yaml.safe_dump(doc))
    result = run(path, in_process=True, out=tmp_path / "runs", picture=False)
    assert result.success, result.error
    scans = {t: np.frombuffer(m.ranges, dtype=np.float32)
             for t, m in result.messages("/robot_0/scan")}
    front = len(scans[0]) // 2  # angle 0: straight ahead
    assert scans[100_000_000][front] > 1.0  # nothing there yet
    assert scans[200_000_000][front] == pytest.approx(0.7, abs=0.15)  # the post's near side


NAV_EVENTS = """
name: bad_events
duration: 2s
world: {world}
goal: {{x: 3.0, y: 3.0}}
events:
{events}
nodes:
  - name: physics
    kind: physics
    rate: 50
    params:
      start: {{x: -3.0, y: -3.0, yaw: 0.785}}
    inputs:
      - {{topic: /cmd_vel, mode: delayed}}
"""


@pytest.mark.parametrize(("events", "key", "words"), [
    ("- {at: 1s, spawn: {name: b, shape: cone, size: [1], pose: {x: 0, y: 3}}}",
     "events[0].spawn.shape", "'box', 'cylinder', 'sphere' or 'mesh'"),
    ("- {at: 1s, spawn: {name: b, shape: box, size: [1, 1], pose: {x: 0, y: 3}}}",
     "events[0].spawn", "a box needs size [x, y, z]"),
    ("- {at: 1s, spawn: {name: b, shape: box, size: [.2, .2, .2], pose: {x: 0, y: 3}, "
     "static: false}}", "events[0].spawn", "needs mass"),
    ("- {at: 15ms, spawn: {name: b, shape: sphere, size: [.1], pose: {x: 0, y: 3}}}",
     "events[0] (b).at", "not on a tick of the physics node (period 20ms)"),
    ("- {at: 3s, spawn: {name: b, shape: sphere, size: [.1], pose: {x: 0, y: 3}}}",
     "events[0] (b).at", "after the run's end"),
    ("- {at: 1s, spawn: {name: pillar_a, shape: sphere, size: [.1], pose: {x: 0, y: 3}}}",
     "events[0] (pillar_a).spawn.name", "already a body or geom of the world"),
    ("- {at: 1s, delete: wall_n}", "events[0] (wall_n).delete", "part of the world file"),
    ("- {at: 1s, delete: world}", "events[0] (world).delete", "part of the world file"),
    ("- {at: 1s, delete: ghost}", "events[0] (ghost).delete", "no object named 'ghost'"),
    ("- {at: 1s, spawn: {name: b, shape: box, size: [.2, .2, .2], pose: {x: 1.6, y: 2.6}}}",
     "events[0] (b).spawn.pose", "inside obstacle 'pillar_a'"),
    ("- {at: 0, spawn: {name: b, shape: box, size: [.2, .2, .2], pose: {x: -3, y: -2.9}}}",
     "events[0] (b).spawn.pose", "overlaps 'base_link' where it starts (-3, -3)"),
    ("- {at: 1s, spawn: {name: b, shape: mesh, mesh: nowhere.stl, pose: {x: 0, y: 3}}}",
     "events[0] (b).spawn.mesh", "does not exist"),
])
def test_bad_events_are_refused_naming_the_key(tmp_path, events, key, words):
    path = tmp_path / "bad.yaml"
    path.write_text(NAV_EVENTS.format(world=NAV_WORLD, events=textwrap.indent(events, "  ")))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    text = str(info.value)
    assert str(path) in text and key in text and words in text, text


def test_a_mesh_that_does_not_load_is_refused_and_an_ascii_one_is_converted(tmp_path):
    (tmp_path / "empty.stl").write_text("solid x\nendsolid x\n")
    ascii_stl = ROOT / "tests" / "robots" / "meshbot_description" / "meshes" / "base_ascii.stl"
    path = tmp_path / "bad.yaml"
    path.write_text(NAV_EVENTS.format(world=NAV_WORLD, events=textwrap.indent(
        "- {at: 1s, spawn: {name: a, shape: mesh, mesh: empty.stl, pose: {x: 0, y: 3}}}\n"
        f"- {{at: 1s, spawn: {{name: b, shape: mesh, mesh: {ascii_stl}, pose: {{x: 0, y: 3}}}}}}",
        "  ")))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert "events[0] (a).spawn.mesh: mesh file" in str(info.value), str(info.value)
    assert "holds no triangles" in str(info.value) and "(b)" not in str(info.value)


def test_a_bad_event_exits_2_before_anything_starts(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(NAV_EVENTS.format(world=NAV_WORLD, events="  - {at: 1s, delete: ghost}"))
    cli = orchestrate(path, tmp_path / "runs")
    assert cli.code == 2
    assert "events[0] (ghost).delete" in cli.stderr
    assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").iterdir())
