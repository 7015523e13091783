"""A node the user starts (cosim-node) behaves every time: a realtime node waits for its first
inputs, it outlives the shell that started it, and a lockstep node with no orchestrator says
what it waits for."""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import textwrap

import psutil
import pytest
from rclpy.serialization import serialize_message
from std_msgs.msg import Int64

from descriptions.load import load_scenario
from plan.options import RunOptions
from runtime import cosim_node
from runtime.build import make_node
from runtime.protocol import CLOCK_TOPIC, encode_clock
from runtime.realtime import RealtimeRuntime
from runtime.transport.base import Received
from tests.helpers import NAV, ROOT

PR_SET_PDEATHSIG, PR_GET_PDEATHSIG = 1, 2
CHAIN = """
name: chain
duration: 1s
nodes:
  - name: source
    kind: counter
    rate: 100
    params: {output: /a}
  - name: sink
    kind: counter
    rate: 100
    params: {output: /b}
    inputs:
      - {topic: /a, mode: same_tick}
"""


class FakeTransport:
    """Hands the runtime the records queued in ``incoming``; keeps what it publishes."""

    def __init__(self):
        self.incoming: list[Received] = []
        self.published: list[tuple[str, bytes]] = []

    def publisher(self, topic, _msg_type, _depth, latched=False):
        transport = self

        class Pub:
            def publish(self, data):
                transport.published.append((topic, data))

        return Pub()

    def subscription(self, *_args, **_kwargs):
        return None

    def wait(self, _timeout_ns):
        taken, self.incoming = self.incoming, []
        return taken

    def close(self):
        pass


def received(topic: str, data: bytes) -> Received:
    return Received(topic, data, None)


def test_a_realtime_lidar_whose_clock_comes_before_its_world_state_waits(capsys):
    # the reported case: /clock from a realtime physics node before its first world state
    scenario = load_scenario(NAV)
    transport = FakeTransport()
    runtime = RealtimeRuntime(scenario, "lidar", make_node(scenario, "lidar", RunOptions()),
                              transport)
    for k in (0, 5, 10):
        transport.incoming.append(received(CLOCK_TOPIC, encode_clock(k * scenario.tick_ns)))
        now = runtime._receive(0)
        runtime._step(now // scenario.tick_ns)
    assert transport.published == []  # nothing stepped, nothing raised
    err = capsys.readouterr().err
    assert err.count("waiting for the first /cosim/world_state") == 1, err  # said once


def test_a_realtime_node_steps_once_its_same_tick_inputs_arrived(tmp_path, capsys):
    path = tmp_path / "chain.yaml"
    path.write_text(textwrap.dedent(CHAIN))
    scenario = load_scenario(path)
    transport = FakeTransport()
    runtime = RealtimeRuntime(scenario, "sink", make_node(scenario, "sink"), transport)
    assert not runtime.publish_clock
    runtime._step(0)
    assert transport.published == []
    transport.incoming.append(received("/a", serialize_message(Int64(data=7))))
    runtime._receive(0)
    runtime._step(1)
    assert [topic for topic, _ in transport.published] == ["/b"]
    assert "waiting for the first /a" in capsys.readouterr().err


def pdeathsig() -> int:
    value = ctypes.c_int(-1)
    assert ctypes.CDLL(None).prctl(PR_GET_PDEATHSIG, ctypes.byref(value), 0, 0, 0) == 0
    return value.value


@pytest.fixture
def this_process_kept(monkeypatch):
    """cosim_node.main names the process and may arm the parent-death signal: undo both."""
    before = pdeathsig()
    ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, 0, 0, 0, 0)
    monkeypatch.setattr("runtime.parent.name_this_process", lambda _name: None)
    monkeypatch.delenv("COSIM_PARENT_PID", raising=False)
    yield
    ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, before, 0, 0, 0)


def test_only_a_node_an_orchestrator_started_dies_with_its_parent(monkeypatch,
                                                                  this_process_kept):
    monkeypatch.setattr(cosim_node, "run_realtime", lambda *_a: 0)
    monkeypatch.setattr(cosim_node, "run_lockstep", lambda *_a: 0)
    assert cosim_node.main(["physics", "--scenario", str(NAV), "--realtime"]) == 0
    assert pdeathsig() == 0  # started by the user: the user's
    monkeypatch.setenv("COSIM_PARENT_PID", str(os.getppid()))  # as the supervisor sets it
    assert cosim_node.main(["physics", "--scenario", str(NAV)]) == 0
    assert pdeathsig() == signal.SIGTERM


def test_a_realtime_node_started_from_a_script_outlives_the_script(tmp_path):
    path = tmp_path / "one.yaml"
    path.write_text("name: one\nduration: 1s\nnodes:\n  - {name: a, kind: counter, rate: 10, "
                    "params: {output: /a}}\n")
    log = tmp_path / "node.log"
    script = (f"{sys.executable} -m runtime.cosim_node counter --scenario {path} --realtime "
              f"> {log} 2>&1 &\necho $!\n"
              f"until grep -q 'running on wall time' {log}; do sleep 0.1; done\n")
    done = subprocess.run(["sh", "-c", script], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)
    node = psutil.Process(int(done.stdout.split()[0]))
    try:
        with pytest.raises(psutil.TimeoutExpired):  # the script is gone; the node goes on
            node.wait(timeout=1.5)
        assert node.status() != psutil.STATUS_ZOMBIE
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(timeout=30)


def test_a_lockstep_node_with_no_orchestrator_says_what_it_waits_for(monkeypatch, capsys,
                                                                    this_process_kept):
    monkeypatch.setattr(cosim_node, "run_lockstep", lambda *_a: 0)
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    assert cosim_node.main(["control", "--scenario", str(NAV)]) == 0
    err = capsys.readouterr().err
    assert "waiting for an orchestrator's /clock and grants on ROS_DOMAIN_ID=42" in err, err
    assert f"cosim-orchestrate {NAV}" in err and "--realtime" in err
    monkeypatch.setenv("COSIM_PARENT_PID", str(os.getppid()))  # an orchestrator's: no word
    assert cosim_node.main(["control", "--scenario", str(NAV)]) == 0
    assert "waiting for" not in capsys.readouterr().err



def test_a_realtime_node_whose_step_raises_failed_it_is_not_bad_input(tmp_path):
    (tmp_path / "brittle.py").write_text(textwrap.dedent("""
        from std_msgs.msg import Int64

        from nodes.contract import StepNode


        class Brittle(StepNode):
            @classmethod
            def outputs(cls, params):
                return {"/a": Int64}

            def step(self, tick, inputs):
                if tick.index == 2:
                    raise ValueError("a value this node cannot take")
                return {"/a": Int64(data=tick.index)}
    """))
    path = tmp_path / "one.yaml"
    path.write_text("name: one\nduration: 1s\nnodes:\n  - {name: a, module: brittle:Brittle, "
                    "rate: 10}\n")
    done = subprocess.run([sys.executable, "-m", "runtime.cosim_node", "any", "--scenario",
                           str(path), "--realtime"], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 1, done.stderr  # the node failed (2 would say: bad input)
    assert "the node failed: ValueError: a value this node cannot take" in done.stderr
