"""Many robots in one world: the robots: section and its checks, node templates, namespaces
and frames, the lidar seeing other robots, one digest whatever the packing, and the swarm
scenario reaching every goal."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import yaml

from descriptions.load import load_scenario
from nodes.contract import NodeConfig
from nodes.sensors.mirror import WorldMirror
from nodes.sensors.node import SensorsNode
from orchestrator.outputs.bag import BagReader
from plan.errors import ScenarioError
from tests.helpers import ROOT, SCENARIOS, orchestrate

SMALL = SCENARIOS / "swarm_small.yaml"
SWARM = ROOT / "scenarios" / "swarm.yaml"
WORLDS = ROOT / "scenarios" / "worlds"


def small_doc() -> dict:
    """swarm_small with absolute paths, to be changed and written elsewhere."""
    doc = yaml.safe_load(SMALL.read_text())
    doc["world"] = str(WORLDS / "arena.xml")
    doc["robots"]["description"] = str(WORLDS / "robot.xml")
    return doc


def write(tmp_path, doc: dict):
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def refused(tmp_path, doc: dict) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        load_scenario(write(tmp_path, doc))
    return info.value


def named(*robots) -> list[dict]:
    return [{"name": n, "start": {"x": sx, "y": sy}, "goal": {"x": gx, "y": gy}}
            for n, (sx, sy), (gx, gy) in robots]


def test_templates_become_one_node_per_robot_with_namespaced_topics():
    s = load_scenario(SMALL)
    names = [r.name for r in s.robots.robots]
    assert names == ["robot_0", "robot_1", "robot_2", "robot_3"]
    assert list(s.nodes) == ["physics", *[f"{k}@{r}" for k in ("lidar", "control")
                                          for r in names]]
    assert s.nodes["control@robot_2"].output_names == {"/cmd_vel": "/robot_2/cmd_vel",
                                                      "/plan": "/robot_2/plan"}
    assert [i.graph_topic for i in s.nodes["control@robot_2"].inputs] == [
        "/robot_2/odom", "/robot_2/scan"]
    assert [i.graph_topic for i in s.nodes["lidar@robot_2"].inputs] == ["/cosim/world_state"]
    physics = s.nodes["physics"]
    assert [i.graph_topic for i in physics.inputs] == [f"/{r}/cmd_vel" for r in names]
    assert {"/tf", "/tf_static", "/robot_3/odom"} <= set(physics.outputs)
    assert "/odom" not in physics.outputs
    # every start clear of the others by the clearance, goals mirrored through the centre
    for i, a in enumerate(s.robots.robots):
        assert a.goal[:2] == pytest.approx((-a.start[0], -a.start[1]))
        for b in s.robots.robots[i + 1:]:
            assert math.dist(a.start[:2], b.start[:2]) >= 1.0


def test_placement_follows_the_seed(tmp_path):
    doc = small_doc()
    first = load_scenario(write(tmp_path, doc)).robots
    assert load_scenario(write(tmp_path, doc)).robots == first
    doc["seed"] = 4
    assert load_scenario(write(tmp_path, doc)).robots != first


@pytest.mark.parametrize("change, key, words", [
    (lambda d: d["robots"].update(count=60, clearance=1.5), "robots.count", "fit"),
    (lambda d: d["robots"].update(count=None, named=named(
        ("a", (0.0, 2.0), (2.0, 0.0)), ("b", (0.2, 2.1), (-2.0, 0.0)))),
     "robots.named[1].start", "overlap"),
    (lambda d: d["robots"].update(count=None, named=named(
        ("a", (1.3, 1.3), (2.0, 0.0)))), "robots.named[0].start", "inside obstacle"),
    (lambda d: d["robots"].update(count=None, named=named(
        ("a", (0.0, 2.0), (2.0, 0.0)), ("a", (0.0, -2.0), (-2.0, 0.0)))),
     "robots.named[1].name", "one namespace"),
    (lambda d: d["nodes"][2].update(robots=["robot_0", "robot_9"]),
     "nodes[2] (control).robots[1]", "no robot 'robot_9'"),
    (lambda d: d["robots"].update(clearance=0.2), "robots.clearance", "overlap"),
    (lambda d: d.update(world=str(WORLDS / "nav.xml")), "world", "already holds a robot"),
    (lambda d: d["robots"].update(description="nowhere.xml"), "robots.description",
     "does not exist"),
])
def test_bad_robots_are_refused_naming_the_key(tmp_path, change, key, words):
    doc = small_doc()
    change(doc)
    doc["robots"] = {k: v for k, v in doc["robots"].items() if v is not None}
    error = refused(tmp_path, doc)
    assert error.key == key
    assert words in error.problem


def test_a_template_without_robots_is_refused(tmp_path):
    doc = small_doc()
    del doc["robots"]
    assert refused(tmp_path, doc).key == "nodes[1] (lidar).for_each"


def test_cli_refuses_bad_robots_with_exit_2_and_writes_nothing(tmp_path):
    doc = small_doc()
    doc["robots"]["count"] = 200
    out = tmp_path / "runs"
    done = orchestrate(write(tmp_path, doc), out)
    assert done.code == 2
    assert "robots.count" in done.stderr
    assert not out.exists() or not any(out.iterdir())


def test_the_lidar_sees_another_robot_in_front_of_it(tmp_path):
    doc = small_doc()
    doc["robots"] = {"description": doc["robots"]["description"], "named": named(
        ("a", (-2.0, 0.0), (2.0, 0.0)), ("b", (-0.5, 0.0), (-3.0, 2.0)))}
    s = load_scenario(write(tmp_path, doc))
    node = SensorsNode()
    plan = s.nodes["lidar@a"]
    node.reset(0, NodeConfig(name="lidar@a", params=plan.params.model_copy(update={
        "lidar": plan.params.lidar.model_copy(update={"noise_stddev": 0.0, "beams": 360})}),
        tick_ns=s.tick_ns, period_ns=plan.spec.period_ns, world=s.world, layout=s.robots))
    mirror = WorldMirror(s.world, s.robots)
    data = mirror.data
    from nodes.physics.messages import world_state

    scan = node.step(None, {"/cosim/world_state": world_state(data.qpos, data.qvel)})["/scan"]
    ranges = np.asarray(scan.ranges)
    assert scan.header.frame_id == "a/laser"
    ahead = ranges[180]  # angle 0: straight ahead (a faces +x, towards b)
    laser = mirror.data.site_xpos[mujoco.mj_name2id(mirror.model, mujoco.mjtObj.mjOBJ_SITE,
                                                    "a/laser")]
    radius = node.lidar.caster.others.radius
    assert ahead == pytest.approx(-0.5 - laser[0] - radius, abs=1e-6)
    assert ranges[0] == pytest.approx(laser[0] + 4.0, abs=1e-6)  # behind: the west wall


def test_every_packing_gives_one_digest_and_the_bag_has_every_namespace(tmp_path):
    # the packings are compared over the first second: a divergence shows within the ticks
    # that first exchange messages, and every topic is in the bag by then
    short = ("--duration", "1s", "--quiet")
    reference = orchestrate(SMALL, tmp_path / "in", "--in-process", *short,
                            picture=True)
    assert reference.code in (0, 1), reference.stderr
    digest = reference.manifest["digest"]
    for args in ((), ("--pack", "kind"), ("--pack", "robot"), ("--pack", "kind", "--spread", "2")):
        done = orchestrate(SMALL, tmp_path / "mp", *args, *short)
        assert done.code == reference.code, done.stderr
        assert done.manifest["digest"] == digest, args
    with BagReader(reference.run_dir / "bag") as bag:
        topics = set(bag.counts)
        tf = next(bag.deserialize(raw, "/tf") for topic, _, raw in bag.raw(["/tf"]))
        static = next(bag.deserialize(raw, "/tf_static")
                      for topic, _, raw in bag.raw(["/tf_static"]))
    for r in range(4):
        assert {f"/robot_{r}/odom", f"/robot_{r}/scan", f"/robot_{r}/cmd_vel",
                f"/robot_{r}/plan", f"/robot_{r}/joint_states"} <= topics
    assert {"/tf", "/tf_static"} <= topics
    pairs = {(t.header.frame_id, t.child_frame_id) for t in tf.transforms}
    assert ("map", "robot_3/odom") in pairs and ("robot_3/odom", "robot_3/base_link") in pairs
    assert ("robot_1/base_link", "robot_1/laser") in {
        (t.header.frame_id, t.child_frame_id) for t in static.transforms}
    swarm = reference.manifest["swarm"]
    assert set(swarm["robots"]) == {f"robot_{r}" for r in range(4)}
    assert swarm["totals"]["robots"] == 4
    assert (reference.run_dir / "report.png").stat().st_size > 10_000


def test_swarm_scenario_gets_every_robot_to_its_goal(tmp_path):
    done = orchestrate(SWARM, tmp_path, "--in-process", "--quiet", timeout=600)
    assert done.code == 0, done.stdout + done.stderr
    swarm = done.manifest["swarm"]
    assert swarm["totals"]["arrived"] == swarm["totals"]["robots"] == 8
    assert all(r["arrived"] and r["time_to_goal"] > 0 for r in swarm["robots"].values())
    assert done.manifest["outcome"]["collisions"] == 0
    # they crossed: each robot's goal is on the other side of the arena from its start
    doc = yaml.safe_load(SWARM.read_text())
    for robot in doc["robots"]["named"]:
        assert math.dist((robot["start"]["x"], robot["start"]["y"]),
                         (robot["goal"]["x"], robot["goal"]["y"])) > 6.0


SWARM_USD = ROOT / "scenarios" / "swarm_usd.yaml"


def test_a_usd_stage_of_instanceable_robot_prims_loads_as_one_robot_each(tmp_path):
    s = load_scenario(SWARM_USD)
    ring = {r["name"]: r for r in yaml.safe_load(SWARM.read_text())["robots"]["named"]}
    assert [r.name for r in s.robots.robots] == list(ring)
    for robot in s.robots.robots:  # placed at the prims' poses, as swarm.yaml places them
        start = ring[robot.name]["start"]
        assert robot.start == pytest.approx((start["x"], start["y"], start["yaw"]), abs=1e-3)
    assert s.robots.description == WORLDS / "robot.xml"
    done = orchestrate(SWARM_USD, tmp_path, "--in-process", "--export-usd", "--duration",
                       "1s", "--set", "success.reach_goal=false", "--quiet")
    assert done.code == 0, done.stderr
    usd = (done.run_dir / "run.usda").read_text()
    assert all(f'"mujoco:body_name" = "robot_{i}/base_link"' in usd for i in range(8))


@pytest.mark.parametrize("change, key", [
    (lambda named: named[0].update(start={"x": 0.0, "y": 0.0}), "robots.named[0].start"),
    (lambda named: named.pop(), "robots.named"),
    (lambda named: named[0].update(name="robot_9"), "robots.named[0].name"),
])
def test_a_usd_swarm_stage_refuses_goals_that_do_not_match_its_robots(tmp_path, change, key):
    doc = yaml.safe_load(SWARM_USD.read_text())
    doc["world"] = str(WORLDS / "swarm.usda")
    change(doc["robots"]["named"])
    assert refused(tmp_path, doc).key == key


def test_a_templated_foreign_program_runs_once_per_robot_in_its_namespace(tmp_path):
    done = orchestrate(SCENARIOS / "swarm_foreign.yaml", tmp_path, "--quiet")
    assert done.code == 0, done.stderr
    with BagReader(done.run_dir / "bag") as bag:
        data: dict[str, list[int]] = {}
        for topic, _, raw in bag.raw(None):
            if topic.endswith(("/source", "/echoed")):
                data.setdefault(topic, []).append(bag.deserialize(raw, topic).data)
    for robot in ("robot_0", "robot_1"):
        assert len(data[f"/{robot}/echoed"]) == 101  # ticks 0..100 of 1 s at 100 Hz
        assert data[f"/{robot}/echoed"] == [v + 1 for v in data[f"/{robot}/source"]]


def test_an_error_in_a_template_names_the_instance_and_the_file_entry(tmp_path):
    doc = small_doc()
    doc["nodes"][2]["params"] = {"max_speed": -1.0}  # control, the third entry of the file
    error = refused(tmp_path, doc)
    assert error.key == "nodes[2] (control@robot_0).params.max_speed"
