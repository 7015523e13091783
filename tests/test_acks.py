"""AckBook: acknowledgements in any arrival order fold into the same digest; the window."""

from __future__ import annotations

import random

from orchestrator.lockstep.acks import AckBook
from plan.schedule import SAME_TICK, Edge, Schedule
from runtime.exchange import RunDigest
from runtime.protocol import Done


def schedule() -> Schedule:
    """physics every tick, camera (a leaf) every 3rd, control every 2nd."""
    return Schedule(10, 11, {"physics": 1, "camera": 3, "control": 2},
                    [Edge("camera", "physics", "/state", SAME_TICK),
                     Edge("control", "physics", "/state", SAME_TICK)])


def done(k: int, node: str, digest: str | None = None) -> Done:
    """An activation reported done, with a made-up digest."""
    return Done(node, k, digest or f"{k:02x}{node.encode().hex()}".ljust(64, "0"))


def acks(sched: Schedule) -> list[Done]:
    """One report per (tick, due node)."""
    return [done(k, n) for k in range(sched.n_ticks) for n in sched.due(k)]


def test_arrival_order_does_not_change_the_digest():
    sched = schedule()
    reference = RunDigest()
    for s in acks(sched):
        reference.add(s.tick, s.node, bytes.fromhex(s.digest))
    for seed in range(5):
        book = AckBook(sched)
        for k in range(sched.n_ticks):
            book.expect(k, 0.0, 1.0)
        shuffled = acks(sched)
        random.Random(seed).shuffle(shuffled)
        for s in shuffled:
            assert book.record(s, 0.0, 1.0)
            book.take_folded()
        assert not book.pending()
        assert book.next_fold == sched.n_ticks
        assert book.hexdigest() == reference.hexdigest()


def test_a_lagging_leaf_blocks_only_when_due_again():
    sched = schedule()
    book = AckBook(sched, frozenset({"camera"}))
    book.expect(0, 0.0, 1.0)
    for name in ("physics", "control"):
        book.record(done(0, name), 0.0, 1.0)
    assert book.may_start(1, window=1)  # camera may still render tick 0 during tick 1
    assert book.may_start(2, window=1)
    assert not book.may_start(3, window=1)  # ... but not when it is due again
    assert book.may_start(3, window=2)


def test_window_bounds_how_far_a_node_may_be_behind():
    sched = schedule()
    book = AckBook(sched)
    for k in range(4):
        book.expect(k, 0.0, 1.0)
    assert book.may_start(4, window=5)
    assert not book.may_start(4, window=4)  # physics still owes tick 0
    book.record(done(0, "physics"), 0.0, 1.0)
    assert not book.may_start(4, window=4)  # camera and control still owe tick 0
    book.record(done(0, "camera"), 0.0, 1.0)
    book.record(done(0, "control"), 0.0, 1.0)
    assert book.may_start(4, window=4)


def test_decided_ticks_come_in_order_without_waiting_for_lagging_nodes():
    sched = schedule()
    book = AckBook(sched, frozenset({"camera"}))
    for k in range(3):
        book.expect(k, 0.0, 1.0)
    book.record(done(1, "physics"), 0.0, 1.0)
    assert book.take_decided() is None  # tick 0 first
    book.record(done(0, "physics"), 0.0, 1.0)
    book.record(done(0, "control"), 0.0, 1.0)
    tick, statuses = book.take_decided()
    assert tick == 0 and set(statuses) == {"physics", "control"}
    assert book.take_decided()[0] == 1  # physics alone is due at 1
    assert book.take_folded() == []  # the camera's tick 0 is still owed
    book.record(done(0, "camera"), 0.0, 1.0)
    assert [t for t, _ in book.take_folded()] == [0, 1]


def test_close_drops_ticks_after_the_end_from_digest_and_debts():
    sched = schedule()
    book, reference = AckBook(sched), RunDigest()
    for k in range(4):
        book.expect(k, 0.0, 1.0)
    book.close(2)
    for s in acks(sched):
        if s.tick < 4:
            assert book.record(s, 0.0, 1.0) == (s.tick < 2)
        if s.tick < 2:
            reference.add(s.tick, s.node, bytes.fromhex(s.digest))
    book.take_folded()
    assert not book.pending()
    assert book.hexdigest() == reference.hexdigest()


def test_a_nodes_deadline_runs_from_when_it_can_start_the_tick():
    sched = schedule()
    book = AckBook(sched)
    book.expect(0, 0.0, 1.0)
    book.expect(1, 0.0, 1.0)  # published early: physics cannot start it before tick 0
    book.record(done(0, "camera"), 0.5, 1.0)
    book.record(done(0, "control"), 0.5, 1.0)
    book.record(done(0, "physics"), 0.9, 1.0)
    assert book.late(1.5) == []  # physics's tick 1 is due by 1.9, not 1.0
    assert book.late(2.0) == [(1, "physics")]


def test_unowed_acknowledgements_are_refused():
    book = AckBook(schedule())
    book.expect(0, 0.0, 1.0)
    assert book.record(done(0, "physics"), 0.0, 1.0)
    assert not book.record(done(0, "physics"), 0.0, 1.0)
    assert not book.record(done(5, "camera"), 0.0, 1.0)


def test_leaves_of_the_schedule():
    assert schedule().leaves() == ["camera", "control"]
