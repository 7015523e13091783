"""The arm (scenarios/arm.yaml): a 6-joint arm on /joint_commands reaches its last target,
publishes /joint_states and TF for its links, gives one digest in-process and
multi-process, notes a wrong-length command and goes on, and refuses a wrong-length target
in the scenario."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from tests.helpers import ROOT, orchestrate

ARM = ROOT / "scenarios" / "arm.yaml"
JOINTS = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]
LINKS = ["shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link",
         "wrist_3_link"]


def bag_messages(run_dir: Path, topic: str) -> list:
    """The messages of ``topic`` in a run's bag, in order, decoded by rosbags alone."""
    with AnyReader([run_dir / "bag"], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        conns = [c for c in r.connections if c.topic == topic]
        return [r.deserialize(raw, c.msgtype) for c, _, raw in r.messages(connections=conns)]


@pytest.fixture(scope="module")
def in_process(tmp_path_factory):
    """One in-process run of scenarios/arm.yaml as it is."""
    run = orchestrate(ARM, tmp_path_factory.mktemp("arm"), "--in-process", "--quiet")
    assert run.code == 0, run.stderr
    return run


def test_the_arm_reaches_its_last_target(in_process):
    last = yaml.safe_load(ARM.read_text())["nodes"][1]["params"]["targets"][-1]
    outcome = in_process.manifest["outcome"]
    assert outcome["status"] == "success" and outcome["stopped_early"]
    assert outcome["metrics_by_node"]["arm"]["target"] == 2.0  # went through all three
    states = bag_messages(in_process.run_dir, "/joint_states")
    final = states[-1]
    assert list(final.name) == JOINTS
    assert max(abs(p - t) for p, t in zip(final.position, last, strict=True)) <= 0.05
    assert max(abs(p - t) for p, t in zip(states[0].position, last, strict=True)) > 0.5


def test_tf_carries_every_link_of_the_arm(in_process):
    tf = bag_messages(in_process.run_dir, "/tf")[-1]
    parents = {t.child_frame_id: t.header.frame_id for t in tf.transforms}
    chain = ["base_link", *LINKS]
    for parent, child in zip(chain, chain[1:], strict=False):
        assert parents[child] == parent
    static = bag_messages(in_process.run_dir, "/tf_static")[0]
    assert {(t.header.frame_id, t.child_frame_id) for t in static.transforms} >= {
        ("wrist_3_link", "tool0")}


def test_multi_process_digest_equals_in_process(in_process, tmp_path):
    run = orchestrate(ARM, tmp_path, "--quiet")
    assert run.code == 0, run.stderr
    assert run.manifest["digest"] == in_process.manifest["digest"]


def test_a_wrong_length_joint_command_is_noted_and_the_run_goes_on(tmp_path):
    five = JOINTS[:5]
    run = orchestrate(ARM, tmp_path, "--in-process", "--quiet", "--duration", "1s",
                      "--set", f"nodes.arm.params.joints={five}",
                      "--set", "nodes.arm.params.targets=[[0.1, 0.1, 0.1, 0.1, 0.1]]")
    assert run.code == 1, run.stderr  # the goal is not met; nothing failed
    manifest = run.manifest
    assert manifest["outcome"]["status"] == "goal_not_met"
    assert manifest["ticks"] == 51  # the whole second
    notes = [n for n in manifest["notes"] if n["node"] == "physics"]
    assert len(notes) == 1
    assert "carries 5 positions, this robot takes 6" in notes[0]["text"]


def refused(tmp_path: Path, old: str, new: str) -> str:
    """The stderr of arm.yaml with ``old`` replaced by ``new``, after checking that it exits
    2 and writes nothing."""
    bad = tmp_path / "arm.yaml"
    bad.write_text(ARM.read_text().replace(old, new))
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "arm.xml").write_text((ROOT / "scenarios/worlds/arm.xml").read_text())
    out = tmp_path / "runs"
    run = orchestrate(bad, out, "--in-process")
    assert run.code == 2, run.stderr
    assert not out.exists() or not any(out.iterdir())
    return run.stderr


def test_a_target_of_the_wrong_length_is_exit_2_naming_the_key(tmp_path):
    err = refused(tmp_path, "- [0.0, 0.6, 0.8, -0.4, 0.0, 1.0]", "- [0.0, 0.6, 0.8]")
    assert "nodes[1] (arm).params.targets[1]" in err and "3 positions for 6 joints" in err


def test_a_target_outside_a_joint_range_is_exit_2_naming_the_key(tmp_path):
    err = refused(tmp_path, "- [0.8, -0.5, 1.0,", "- [0.8, -2.5, 1.0,")
    assert "nodes[1] (arm).params.targets[0]" in err and "'shoulder_lift'" in err


def test_a_joint_goal_on_an_unknown_joint_is_exit_2_naming_the_key(tmp_path):
    err = refused(tmp_path, "elbow: 1.1,", "elbw: 1.1,")
    assert "joint_goal.positions.elbw" in err and "no hinge or slide joint 'elbw'" in err


def test_a_fixed_base_takes_no_cmd_vel_exit_2(tmp_path):
    run = orchestrate(ARM, tmp_path, "--in-process", "--set",
                      "nodes.physics.inputs=[{topic: /joint_commands, mode: delayed}, "
                      "{topic: /cmd_vel, mode: delayed}]")
    assert run.code == 2
    assert "nodes[0] (physics).inputs[1].topic: this node does not take /cmd_vel" in run.stderr
    assert not any(tmp_path.iterdir())
