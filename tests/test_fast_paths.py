"""What makes lockstep fast must not change what it computes: batched 'done' reports,
the pipelined clock and forked node processes, each against its plain counterpart."""

from __future__ import annotations

import math

import pytest

from runtime.protocol import (
    DONE,
    Done,
    MetricBook,
    MetricChanges,
    decode_status,
    done_status,
    encode_status,
)
from tests.helpers import SCENARIOS, orchestrate

PROTOCOL = SCENARIOS / "protocol.yaml"


def test_a_batch_of_done_reports_round_trips_through_diagnostic_status_bytes():
    batch = [Done("lidar", 5, "ab" * 32, 1200, {"measurements": 1.0, "x": -0.5}),
             Done("lidar", 10, "cd" * 32, 987654321, {"measurements": 2.0}),
             Done("lidar", 15, "ef" * 32, 0, {"measurements": 3.0, "x": math.inf})]
    decoded = decode_status(encode_status(done_status("lidar", batch)))
    assert decoded.state == DONE and decoded.node == "lidar" and decoded.tick == 15
    assert decoded.done == batch  # metrics absent at a tick stay absent, floats exact
    assert decoded.values["ticks"] == "5 10 15"  # readable with ROS tools


def test_a_packed_process_reports_its_nodes_activations_in_one_message():
    a0, a1 = MetricChanges(), MetricChanges()
    batch = [Done("lidar@r0", 5, "ab" * 32, 10, *a0.report({"m": 1.0})),
             Done("lidar@r0", 10, "cd" * 32, 11, *a0.report({"m": 1.0})),
             Done("lidar@r1", 5, "ef" * 32, 12, *a1.report({"m": 2.0, "k": 3.0}))]
    decoded = decode_status(encode_status(done_status("lidar@r0", batch)))
    assert decoded.values["nodes"] == "lidar@r0 lidar@r0 lidar@r1"
    assert decoded.done == batch
    MetricBook().complete(decoded)  # each node's metrics completed from its own previous
    assert [d.metrics for d in decoded.done] == [{"m": 1.0}, {"m": 1.0}, {"m": 2.0, "k": 3.0}]
    assert "nodes" not in done_status("lidar@r0", batch[:2]).values  # one node: as before


def test_reports_carry_the_metrics_that_changed_and_the_orchestrator_completes_them():
    steps = [{"a": 1.0, "b": 2.0}, {"a": 1.0, "b": 2.5}, {"a": 1.0, "b": 2.5, "c": 0.0},
             {"a": 1.0, "b": 2.5, "c": -0.0}, {"a": math.nan, "b": 2.5, "c": -0.0},
             {"b": 2.5}, {"b": 2.5}]  # 'a' and 'c' went away: all of them again
    changes, book, sent = MetricChanges(), MetricBook(), []
    for tick, metrics in enumerate(steps):
        values, full = changes.report(dict(metrics))
        sent.append(Done("p", tick, "ab" * 32, 1, values, full))
    assert [len(d.metrics) for d in sent] == [2, 1, 1, 1, 1, 1, 0]
    assert [d.full for d in sent] == [True, False, False, False, False, True, False]
    for batch in (sent[:3], sent[3:4], sent[4:]):  # batches as reports of wake-ups
        status = decode_status(encode_status(done_status("p", batch)))
        book.complete(status)
        for done, metrics in zip(status.done, steps[batch[0].tick:], strict=False):
            assert done.full and {k: repr(v) for k, v in done.metrics.items()} == {
                k: repr(v) for k, v in metrics.items()}
    changes.restart()  # after a reset the first report carries them all
    assert changes.report({"b": 2.5}) == ({"b": 2.5}, True)


def test_status_bytes_are_what_rclpy_writes_and_read_back_from_rclpy_bytes():
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
    from rclpy.serialization import serialize_message

    from runtime.cdr.canonical import canonical_cdr
    from runtime.protocol import ERROR, Status

    status = Status("cam\u00e9ra", ERROR, 7, "d1", "d\u00e9tail \u20ac", {"k": "v\u00e9", "ab": ""})
    msg = DiagnosticStatus(level=DiagnosticStatus.ERROR, name=status.node, message=status.detail,
                           hardware_id=status.digest, values=[
                               KeyValue(key=k, value=v) for k, v in
                               [("state", ERROR), ("tick", "7"), *status.values.items()]])
    rclpy_bytes = canonical_cdr(serialize_message(msg), DiagnosticStatus)
    assert encode_status(status) == rclpy_bytes
    assert decode_status(rclpy_bytes) == status


def test_a_malformed_done_report_is_refused():
    status = done_status("a", [Done("a", 1, "00" * 32)])
    status.values["digests"] += " " + "11" * 32  # one digest too many
    with pytest.raises(ValueError):
        decode_status(encode_status(status))


@pytest.mark.parametrize("variant", [["--no-pipeline"], ["--spawn", "exec"]])
def test_plain_lockstep_and_fresh_interpreters_give_the_same_run(tmp_path, variant):
    fast = orchestrate(PROTOCOL, tmp_path / "fast")
    plain = orchestrate(PROTOCOL, tmp_path / "plain", *variant)
    assert fast.code == plain.code == 0, (fast.stderr, plain.stderr)
    assert fast.manifest["digest"] == plain.manifest["digest"]
    assert fast.manifest["ticks"] == plain.manifest["ticks"]
    ticks = {n: v["ticks"] for n, v in fast.manifest["nodes"].items()}
    assert ticks == {n: v["ticks"] for n, v in plain.manifest["nodes"].items()}
    started = {v["started"] for v in plain.manifest["nodes"].values()}
    assert started == ({"exec"} if "--spawn" in variant else {"fork"})
    options = plain.manifest["options"]
    assert (options["pipeline"], options["spawn"]) == (
        ("--no-pipeline" not in variant), "exec" if "--spawn" in variant else "fork")
    assert {v["started"] for v in fast.manifest["nodes"].values()} == {"fork"}
    assert fast.manifest["startup"]["command_to_first_tick_s"] > 0
