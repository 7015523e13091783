"""Which nodes share a process never changes the result: every packing gives the
in-process digest, and packed nodes share one process."""

from __future__ import annotations

import pytest
import yaml

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from plan.packing import layout_of, process_label
from plan.roles import NodeRole
from tests.helpers import ROOT, SCENARIOS, orchestrate

PROTOCOL = SCENARIOS / "protocol.yaml"
NAV = ROOT / "scenarios" / "nav.yaml"


def test_the_layout_gives_each_node_one_process_and_counts_its_readers(tmp_path):
    """The run's layout, decided once: each node in one process with its role, packed
    consumers counted once as readers, a node you start a process of its own."""
    doc = yaml.safe_load(PROTOCOL.read_text())
    doc["nodes"][1]["external"] = True  # middle: started by you
    doc["external"] = {"rate": 10, "topics": {"/goal_pose": "geometry_msgs/msg/PoseStamped"}}
    path = tmp_path / "roles.yaml"
    path.write_text(yaml.safe_dump(doc))
    scenario = load_scenario(path)
    roles = {name: plan.role for name, plan in scenario.nodes.items()}
    assert roles == {"source": NodeRole.STEP, "middle": NodeRole.USER_STARTED,
                     "loop": NodeRole.STEP, "sink": NodeRole.STEP, "slow": NodeRole.STEP,
                     "external": NodeRole.ORCHESTRATOR}
    layout = layout_of(scenario, "robot")
    assert [(p.label, p.role) for p in layout.processes] == [
        ("source+loop+sink+slow", NodeRole.STEP), ("middle", NodeRole.USER_STARTED),
        ("external", NodeRole.ORCHESTRATOR)]
    assert [p.label for p in layout.node_processes] == ["source+loop+sink+slow", "middle"]
    assert layout.subscribers("middle") == {"/middle": 1}  # loop and sink share a process
    assert layout.subscribers("source") == {"/source": 1}
    alone = layout_of(scenario, None)
    assert alone.subscribers("middle") == {"/middle": 2}
    assert alone.process_of["sink"] == "sink"


def pids(run) -> dict[str, int]:
    return {name: entry["pid"] for name, entry in run.manifest["nodes"].items()}


@pytest.mark.parametrize("pack", ["node", "kind", "robot"])
def test_every_packing_gives_the_in_process_digest(tmp_path, pack):
    reference = run_in_process(load_scenario(PROTOCOL)).digest
    done = orchestrate(PROTOCOL, tmp_path, "--pack", pack, "--quiet")
    assert done.code == 0, done.stderr
    assert done.manifest["digest"] == reference
    by_pid = pids(done)
    if pack == "node":
        assert len(set(by_pid.values())) == 5
    elif pack == "kind":  # counters together, the integrator alone
        assert by_pid["source"] == by_pid["middle"] == by_pid["sink"] == by_pid["slow"]
        assert by_pid["loop"] != by_pid["source"]
    else:
        assert len(set(by_pid.values())) == 1


def test_process_keys_pack_nav_with_the_same_digest(tmp_path):
    doc = yaml.safe_load(NAV.read_text())
    doc["duration"] = "3s"
    doc["world"] = str((NAV.parent / doc["world"]).resolve())
    for node in doc["nodes"]:
        node["process"] = "sensing" if node["kind"] == "sensors" else None
        if node["process"] is None:
            node.pop("process")
    path = tmp_path / "nav_packed.yaml"
    path.write_text(yaml.safe_dump(doc))
    inproc = orchestrate(path, tmp_path / "i", "--in-process", "--quiet")
    packed = orchestrate(path, tmp_path / "p", "--quiet")
    assert packed.code == inproc.code, packed.stderr
    assert packed.manifest["digest"] == inproc.manifest["digest"]
    by_pid = pids(packed)
    assert by_pid["lidar"] == by_pid["camera"] != by_pid["physics"]


def test_a_foreign_program_cannot_share_a_process(tmp_path):
    doc = yaml.safe_load((SCENARIOS / "foreign_echo.yaml").read_text())
    doc["nodes"][1]["process"] = "together"
    doc["nodes"][1]["command"][1] = str(SCENARIOS.parent / "programs" / "echo.py")
    path = tmp_path / "echo.yaml"
    path.write_text(yaml.safe_dump(doc))
    done = orchestrate(path, tmp_path / "runs")
    assert done.code == 2 and "nodes[1] (echo).process" in done.stderr
    assert "only cosim nodes the orchestrator starts share a process" in done.stderr


def test_a_long_packed_group_gets_a_short_process_label():
    # a swarm's controllers packed by kind: the joined names would be a log file name over
    # the file system's 255-character limit
    names = [f"control@robot_{i}" for i in range(64)]
    label = process_label(names)
    assert label == "control@robot_0+63_more"
    assert process_label(["physics", "lidar"]) == "physics+lidar"


def test_spread_splits_each_kind_over_at_most_n_processes_in_runs():
    scenario = load_scenario(SCENARIOS / "swarm_small.yaml")  # 4 robots: lidar, control each

    def groups(spread):
        return [list(p.names) for p in layout_of(scenario, "kind", spread).node_processes]

    assert ["physics"] in groups(2)
    assert ["lidar@robot_0", "lidar@robot_1"] in groups(2)
    assert ["control@robot_2", "control@robot_3"] in groups(2) and len(groups(2)) == 5
    assert len(groups(9)) == 9  # never more processes than nodes
    assert groups(1) == [list(p.names) for p in layout_of(scenario, "kind").node_processes]


@pytest.mark.parametrize("args", [("--pack", "kind", "--spread", "0"), ("--spread", "2"),
                                  ("--pack", "robot", "--spread", "2")])
def test_a_bad_spread_is_refused_with_exit_2(tmp_path, args):
    done = orchestrate(PROTOCOL, tmp_path, *args, "--quiet")
    assert done.code == 2 and "spread" in done.stderr and "pack kind" in done.stderr
    assert done.run_dir is None


def test_nodes_that_only_read_their_inputs_share_one_decoded_sample():
    from std_msgs.msg import Float64MultiArray

    from runtime.cdr.encode import encode
    from runtime.exchange import InputHistory, SharedDecoder

    shared = SharedDecoder()
    data = encode(Float64MultiArray(data=[1.0, 2.0]))
    readers = [InputHistory("/w", Float64MultiArray, shared) for _ in range(3)]
    own = InputHistory("/w", Float64MultiArray)  # a node that may change its inputs
    for history in [*readers, own]:
        history.push_bytes(0, data)
    taken = [h.take(0) for h in readers]
    assert taken[0] is taken[1] is taken[2] and list(taken[0].data) == [1.0, 2.0]
    assert own.take(0) is not taken[0]
    other = bytearray(data)  # equal bytes of another sample: decoded on their own
    assert shared.decode(bytes(other), Float64MultiArray) is not taken[0]
