"""Crowds that get through (nodes/control/crowd.py): two groups swapping rooms through one
door and a plaza crossed from every direction reach every goal with no collision, robots
keep apart, a held robot says by whom, and the run is one digest in-process and packed."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from nodes.control.crowd import Line, orca_line, orca_velocity
from orchestrator.api import run
from orchestrator.outputs.bag import BagReader
from plan.poses import pose_of
from tests.helpers import ROOT, orchestrate

DOOR = ROOT / "scenarios" / "crowd_door.yaml"
PLAZA = ROOT / "scenarios" / "crowd_plaza.yaml"
FOOTPRINT = 2 * 0.23  # two robot radii (robot.xml): nearer than this is a touch


def closest_approach(run_dir) -> float:
    """The least distance between two robots' bases over the run, from the bag's odometry."""
    tracks: dict[int, dict[str, tuple[float, float]]] = {}
    with BagReader(run_dir / "bag") as bag:
        topics = [t for t in bag.counts if t.endswith("/odom")]
        for topic, _, raw in bag.raw(topics):
            msg = bag.deserialize(raw, topic)
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            tracks.setdefault(stamp, {})[topic] = pose_of(msg.pose.pose)[:2]
    least = math.inf
    for poses in tracks.values():
        xy = np.array(list(poses.values()))
        d = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
        d[np.diag_indices(len(xy))] = math.inf
        least = min(least, float(d.min()))
    return least


def crowd_run(scenario, tmp_path, **overrides):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return run(scenario, in_process=True, out=tmp_path, check=True, **overrides, picture=False)


@pytest.mark.parametrize("scenario", [DOOR, PLAZA], ids=["door_swap", "plaza"])
def test_a_crowd_reaches_every_goal_without_touching(tmp_path, scenario):
    done = crowd_run(scenario, tmp_path)
    swarm = done.manifest["swarm"]
    assert swarm["totals"]["arrived"] == swarm["totals"]["robots"] == 8, swarm["robots"]
    assert swarm["totals"]["collisions_robots"] == swarm["totals"]["collisions_obstacles"] == 0
    assert done.success
    assert closest_approach(done.run_dir) > FOOTPRINT + 0.05
    if scenario == DOOR:  # one group waited for the other at the door
        waits = [m.get("door_waits", 0) for name, m in done.metrics_by_node.items()
                 if name.startswith("control@")]
        assert sum(w > 0 for w in waits) >= 4


def test_a_held_robot_says_which_robot_holds_it_and_where(tmp_path):
    # robot_4..7 wait for robot_0..3 to come through the door; told to report after 5 s
    done = crowd_run(DOOR, tmp_path, duration="20s", params={"control": {"crowd_report_s": 5}},
                     overrides={"success.reach_goal": False})
    texts = [n["text"] for n in done.manifest["notes"] if n["node"] == "control@robot_5"]
    assert any(t.startswith("blocked by robot_") and "at the door (0.0, " in t
               and t.endswith("for 5 s") for t in texts), texts


def test_one_digest_in_process_and_packed(tmp_path):
    reference = orchestrate(DOOR, tmp_path / "in", "--in-process", "--quiet", "--duration",
                            "9s", "--set", "success.reach_goal=false")
    assert reference.code == 0, reference.stderr
    packed = orchestrate(DOOR, tmp_path / "mp", "--pack", "kind", "--quiet", "--duration",
                         "9s", "--set", "success.reach_goal=false")
    assert packed.code == 0, packed.stderr
    assert packed.manifest["digest"] == reference.manifest["digest"]


def test_orca_lets_two_robots_head_on_pass_each_on_its_right():
    # robot at the origin going +x at 0.5 m/s, another 2 m ahead coming at it
    line = orca_line(np.array([2.0, 0.0]), np.array([1.0, 0.0]), np.array([0.5, 0.0]),
                     0.62, 2.0, 0.1, 0.5)
    assert isinstance(line, Line)
    u = orca_velocity([line], 0, np.array([0.5, 0.0]), 0.5)
    assert u[1] < -0.05  # to the right (negative y when heading +x)
    assert math.hypot(*u) <= 0.5 + 1e-9
    alone = orca_velocity([], 0, np.array([0.3, 0.1]), 0.5)
    assert alone == pytest.approx([0.3, 0.1])


def test_crowd_worlds_follow_the_seed_and_keep_their_robots_apart(tmp_path):
    from bench.crowd_worlds import FAMILIES, MOUTH, SPACING, generate

    worlds = [generate(seed) for seed in range(9)]
    assert [w.family for w in worlds] == list(FAMILIES) * 3
    assert generate(4) == worlds[4] and generate(5) != worlds[4]
    for w in worlds:
        assert 8 <= w.robots <= 32
        for spots in ([s[:2] for s in w.starts], list(w.goals)):
            xy = np.array(spots)
            d = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
            assert d[~np.eye(len(xy), dtype=bool)].min() >= SPACING
        if w.family != "plaza":  # every start and goal away from the passage's mouths
            doors = [s for s in w.shapes if s.name.startswith("divide")]
            y = (doors[0].y + doors[0].hy + doors[1].y - doors[1].hy) / 2
            for x0, y0 in [s[:2] for s in w.starts] + list(w.goals):
                assert min(math.hypot(x0 - x, y0 - y)
                           for x in (-doors[0].hx, doors[0].hx)) >= MOUTH - 0.06  # jitter
    scenario = worlds[0].write(tmp_path)
    from descriptions.load import load_scenario

    loaded = load_scenario(scenario)
    assert len(loaded.robots.robots) == worlds[0].robots


def test_robots_that_enter_are_seen_by_the_crowd(monkeypatch, tmp_path):
    """A robot entering a crowd's run (a world edited at a tick) is in every robot's view
    from its world state on (its place in that world's qpos), and none before: the crowd
    neither stops nor crashes on the edited world (it did both)."""
    from nodes.control import crowd
    from orchestrator.api import spawn_robot

    views: dict[tuple[str, int], set[int]] = {}
    update = crowd.Others.update

    def spy(self, msg):
        update(self, msg)
        assert self.known, (self.names[self.own], self.world)
        views.setdefault((self.names[self.own], self.world[0]), set()).add(
            int(self.present.sum()))

    monkeypatch.setattr(crowd.Others, "update", spy)
    late = spawn_robot("late", at="1s", start=(-3.0, 2.5, 0.0), goal=(-2.0, 2.5))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        done = run(DOOR, in_process=True, events=[late], duration="2s", check=True,
                   out=tmp_path, picture=False)
    assert done.status in ("success", "goal_not_met")
    assert views[("robot_0", 0)] == {8} and views[("robot_0", 1)] == {9}
    assert views[("late", 1)] == {9} and ("late", 0) not in views
