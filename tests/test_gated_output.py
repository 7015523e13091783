"""What consumers see of a gated foreign program's output (runtime.gated_output): the
latest message at or before each producer tick, none yet before the first, whatever order
its messages and its gate's acknowledgements arrive in; and the gate inside a real rclpy
process makes a best-effort fed subscription reliable."""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys

import pytest
from std_msgs.msg import Int64

from orchestrator.proxies.foreign_launch import GATE_DIR
from runtime.cdr.encode import encode
from runtime.gated_output import GatedChannel, SequenceError
from runtime.transport.base import Received

# producer period 2: ticks 0, 2, 4, 6; messages per tick on this output: 0, 2, 0, 1
COUNTS = [(0, 0), (2, 2), (4, 0), (6, 1)]
VALUES = [10, 11, 12]  # the three messages, in publication order


def events():
    """The program's messages and acknowledgements, each in its own order."""
    messages = [("msg", Received("/out", encode(Int64(data=v)), n + 1))
                for n, v in enumerate(VALUES)]
    acks = [("ack", tick, [0, count]) for tick, count in COUNTS]  # this output is index 1
    return messages, acks


def samples_after(order) -> dict[int, int | None]:
    channel = GatedChannel("/in", "/out", Int64, 2, index=1)
    resolved = []
    for event in order:
        if event[0] == "msg":
            resolved += channel.accept_ticks(event[1])
        else:
            resolved += channel.acknowledged(event[1], event[2])
    assert resolved == [0, 2, 4, 6]
    out = {}
    for tick in resolved:
        msg = channel.history.take(tick)
        out[tick] = None if msg is None else msg.data
    return out


def interleavings(a, b):
    """Every merge of two sequences that keeps each one's order."""
    n = len(a) + len(b)
    for positions in itertools.combinations(range(n), len(a)):
        ia, ib, merged = iter(a), iter(b), []
        for i in range(n):
            merged.append(next(ia) if i in positions else next(ib))
        yield merged


def test_the_latest_sample_at_or_before_each_tick_whatever_the_arrival_order():
    messages, acks = events()
    seen = {json.dumps(samples_after(order)) for order in interleavings(messages, acks)}
    # none yet at tick 0; tick 2's last message; held at tick 4; tick 6's own
    assert seen == {json.dumps({0: None, 2: 11, 4: 11, 6: 12})}


def test_a_lost_message_or_acknowledgement_is_an_error():
    channel = GatedChannel("/in", "/out", Int64, 2, index=0)
    with pytest.raises(SequenceError, match="a message was lost"):
        channel.accept_ticks(Received("/out", encode(Int64(data=1)), 2))
    channel = GatedChannel("/in", "/out", Int64, 2, index=0)
    channel.acknowledged(-1, [])  # ready: not a tick
    with pytest.raises(SequenceError, match="expected tick 0, got 2"):
        channel.acknowledged(2, [1])


PROBE = """
import rclpy
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from std_msgs.msg import Int64
rclpy.init()
node = Node('probe')
fed = node.create_subscription(Int64, '/cosim/feed/p/a', lambda m: None, qos_profile_sensor_data)
other = node.create_subscription(Int64, '/elsewhere', lambda m: None, qos_profile_sensor_data)
print(fed.qos_profile.reliability.name, other.qos_profile.reliability.name)
node.destroy_node()
rclpy.shutdown()
"""


def test_the_gate_makes_a_best_effort_fed_subscription_reliable():
    env = dict(os.environ, COSIM_GATE=json.dumps({"prefix": "/cosim/feed/p/", "node": "p",
                                                  "inputs": [{"topic": "a"}]}))
    env["PYTHONPATH"] = os.pathsep.join([str(GATE_DIR), env.get("PYTHONPATH", "")])
    done = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["RELIABLE", "BEST_EFFORT"]  # only the fed one is changed
