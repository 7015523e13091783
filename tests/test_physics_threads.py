"""MuJoCo's engine thread pool in the physics node (``params.threads``) changes nothing but
the speed: a crowded swarm whose robots drive into each other ends in the same state, bit for
bit, and publishes the same messages with no pool and with one of three threads."""

from __future__ import annotations

import numpy as np
import yaml
from geometry_msgs.msg import Twist

from descriptions.load import load_scenario
from nodes.contract import Tick
from orchestrator.lockstep.inprocess import make_node
from runtime.cdr.encode import encode
from tests.helpers import ROOT

ROBOTS = 12


def crowded(tmp_path, threads: int):
    """Twelve robots packed into a small square, physics with a pool of ``threads``."""
    doc = {
        "name": "crowd", "seed": 5, "duration": "1s",
        "world": str(ROOT / "scenarios" / "worlds" / "arena.xml"),
        "robots": {"description": str(ROOT / "scenarios" / "worlds" / "robot.xml"),
                   "count": ROBOTS, "region": {"x": [-1.6, 1.6], "y": [-1.6, 1.6]},
                   "clearance": 0.7},
        "success": {"reach_goal": False, "max_collisions": 1_000_000},
        "nodes": [{"name": "physics", "kind": "physics", "rate": 50,
                   "params": {"imu": None, "threads": threads},
                   "inputs": [{"topic": "/cmd_vel", "mode": "delayed"}]},
                  # the publishers of /cmd_vel the scenario needs (only physics is built)
                  {"name": "lidar", "kind": "sensors", "for_each": "robot", "rate": 10,
                   "params": {"lidar": {"beams": 8}},
                   "inputs": [{"topic": "/cosim/world_state", "mode": "same_tick"}]},
                  {"name": "control", "kind": "control", "for_each": "robot", "rate": 10,
                   "inputs": [{"topic": "/odom", "mode": "same_tick"},
                              {"topic": "/scan", "mode": "same_tick"}]}],
    }
    path = tmp_path / f"crowd{threads}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return make_node(load_scenario(path), "physics")


def towards_the_middle(node) -> dict[str, Twist]:
    """Every robot full speed ahead, turning towards the middle: they meet and push."""
    out = {}
    for i in range(ROBOTS):
        x, y, yaw = node.swarm.rigs[i].base_pose(node.data)[:3]
        msg = Twist()
        msg.linear.x = 1.0
        msg.angular.z = float(np.clip(np.arctan2(-y, -x) - yaw, -2.5, 2.5))
        out[f"/robot_{i}/cmd_vel"] = msg
    return out


def test_a_thread_pool_gives_the_same_state_and_messages(tmp_path):
    nodes = [crowded(tmp_path, 1), crowded(tmp_path, 3)]
    period_ns = 20_000_000
    contacts = 0
    for k in range(50):
        commands = towards_the_middle(nodes[0])
        outs = [node.step(Tick(k, k * period_ns), commands) for node in nodes]
        assert outs[0].keys() == outs[1].keys()
        for topic, msg in outs[0].items():
            assert encode(msg) == encode(outs[1][topic]), (k, topic)
        model, data = nodes[0].model, nodes[0].data
        roots = [{int(model.body_rootid[model.geom_bodyid[g]]) for g in (c.geom1, c.geom2)}
                 for c in data.contact[:data.ncon]]
        contacts = max(contacts, sum(1 for r in roots if len(r) == 2 and 0 not in r))
    a, b = (node.data for node in nodes)
    assert a.qpos.tobytes() == b.qpos.tobytes() and a.qvel.tobytes() == b.qvel.tobytes()
    assert contacts > 0, "no two robots touched: the pool's parallel parts went untried"
