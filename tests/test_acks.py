"""AckBook: acknowledgements in any arrival order fold into the same digest."""

from __future__ import annotations

import random

from nodes.exchange import RunDigest
from orchestrator.acks import AckBook
from orchestrator.schedule import SAME_TICK, Edge, Schedule


def schedule() -> Schedule:
    """physics every tick, camera (a leaf) every 3rd, control every 2nd."""
    return Schedule(10, 11, {"physics": 1, "camera": 3, "control": 2},
                    [Edge("camera", "physics", "/state", SAME_TICK),
                     Edge("control", "physics", "/state", SAME_TICK)])


def acks(sched: Schedule) -> list[tuple[int, str, str]]:
    """One made-up digest per (tick, due node)."""
    return [(k, n, f"{k:02x}{n.encode().hex()}".ljust(64, "0"))
            for k in range(sched.n_ticks) for n in sched.due(k)]


def test_arrival_order_does_not_change_the_digest():
    sched = schedule()
    reference = RunDigest()
    for k, n, d in acks(sched):
        reference.add(k, n, bytes.fromhex(d))
    for seed in range(5):
        book = AckBook(sched)
        for k in range(sched.n_ticks):
            book.expect(k, sched.due(k), 0.0)
        shuffled = acks(sched)
        random.Random(seed).shuffle(shuffled)
        for k, n, d in shuffled:
            assert book.record(k, n, d)
        assert not book.owed
        assert book.hexdigest() == reference.hexdigest()


def test_leaf_blocks_only_when_due_again():
    sched = schedule()
    book = AckBook(sched)
    book.expect(0, sched.due(0), 0.0)
    for name in ("physics", "control"):
        book.record(0, name, "00" * 32)
    leaves = frozenset({"camera"})
    assert book.blocking(1, leaves) == []  # camera may still render tick 0 during tick 1
    assert book.blocking(3, leaves) == [(0, "camera")]  # ... but not when it is due again
    assert book.blocking(None, leaves) == [(0, "camera")]


def test_unowed_acknowledgements_are_refused():
    book = AckBook(schedule())
    book.expect(0, ("physics",), 0.0)
    assert book.record(0, "physics", "11" * 32)
    assert not book.record(0, "physics", "11" * 32)
    assert not book.record(5, "camera", "11" * 32)


def test_leaves_of_the_schedule():
    assert schedule().leaves() == ["camera", "control"]
