"""A starting node reports its discovery on change and as a slow heartbeat, not every check."""

from runtime.lockstep import HEARTBEAT_S, STATUS_PERIOD_S, LockstepRuntime
from runtime.protocol import READY, WAITING


def starting(unmatched: list[list[str]]):
    rt = object.__new__(LockstepRuntime)
    rt.name = "lidar"
    rt._start_report, rt._next_start_check, rt._next_heartbeat = None, 0.0, 0.0
    rt.checks = 0

    def check():
        rt.checks += 1
        return unmatched[min(rt.checks, len(unmatched)) - 1]

    rt.unmatched = check
    rt.sent = []
    rt.report = lambda status: rt.sent.append((status.state, status.detail))
    return rt


def test_reports_only_changes_and_a_heartbeat():
    rt = starting([["/scan (0/1 subscriptions)"]] * 3 + [[]])
    t = 1.0
    for _ in range(160):  # four seconds of checks, ready after three
        rt.report_start(t)
        t += STATUS_PERIOD_S / 2
    # waiting named once (repeated by the heartbeat only), then ready once
    assert rt.sent[0] == (WAITING, "/scan (0/1 subscriptions)")
    assert rt.sent[1] == (READY, "")
    assert HEARTBEAT_S == 1.0
    assert len(rt.sent) == 2 + 3  # heartbeats 1, 2 and 3 s after 'ready'
    assert set(rt.sent[2:]) == {(READY, "")}
    assert rt.checks == 4  # ready: the orchestrator knows it, discovery is not checked again


def test_a_period_spreads_the_checks():
    rt = starting([["/clock (0/1 publishers)"]])
    for i in range(100):
        rt.report_start(1.0 + i * STATUS_PERIOD_S, period=10 * STATUS_PERIOD_S)
    assert rt.checks == 10
