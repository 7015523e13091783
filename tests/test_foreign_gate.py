"""The foreign program gate's decisions (runtime/foreign_gate/cosim_gate.py), without rclpy:
which gated subscriptions one executor wait may hold, when the program's timers are held
back, and when a tick is acknowledged. Stand-ins replace the executor, its subscriptions and
the probe of which subscriptions hold data; the end-to-end runs are in
test_foreign_determinism.py."""

from __future__ import annotations

import threading
from types import SimpleNamespace

import pytest

from runtime.foreign_gate import cosim_gate
from runtime.foreign_gate.cosim_gate import READY_TICK, Gate, GateConfig, _ExecutorView

PREFIX = "/cosim/feed/fusion/"
CLOCK, A, B = PREFIX + "clock", PREFIX + "a", PREFIX + "b"


class Task:
    """An executor task that is done or not."""

    def __init__(self, done: bool):
        self._done = done

    def done(self) -> bool:
        return self._done


class SingleThreadedExecutor:
    """What the gate reads of an executor: its tasks (the in-flight callbacks)."""

    def __init__(self):
        self.context = None
        self._tasks_lock = threading.Lock()
        self._tasks: list = []

    def running(self, *done: bool) -> None:
        """Set the executor's tasks: one per value, done or still in flight."""
        self._tasks = [(Task(d), None, None) for d in done]


class MultiThreadedExecutor(SingleThreadedExecutor):
    """The same, named as rclpy's multi-threaded executor (its callbacks may overlap)."""


class Sub:
    """A gated subscription: its handle's pointer, and how many publishers it matched."""

    def __init__(self, pointer: int, publishers: int = 1):
        self.handle = SimpleNamespace(pointer=pointer)
        self.publishers = publishers

    def get_publisher_count(self) -> int:
        return self.publishers


class Timer:
    """A program timer whose readiness the test sets."""

    def __init__(self, pointer: int):
        self.ready = False
        outer = self

        class Handle:
            def __enter__(self):
                return self

            def __exit__(self, *exc):
                return False

            pointer = 0

            def is_timer_ready(self):
                return outer.ready

        self.handle = Handle()
        self.handle.pointer = pointer


class Harness:
    """A gate over one executor with subscriptions clock, a, b (created in that order)."""

    def __init__(self, executor=None, inputs=("a", "b"), **config):
        raw = {"prefix": PREFIX, "node": "fusion", "tick_ns": 10_000_000,
               "inputs": list(inputs), **config}
        self.gate = Gate(GateConfig.from_json(__import__("json").dumps(raw)))
        self.acks: list[int] = []
        self.present: set[int] = set()
        self.gate._ensure_ack_publisher = lambda context: None
        self.gate._ack = self.acks.append
        self.gate._probe = lambda view: frozenset(self.present)
        self.subs = {CLOCK: Sub(1), A: Sub(2), B: Sub(3)}
        self.timer = Timer(9)
        self.executor = executor or SingleThreadedExecutor()
        gated = [(sub, topic) for topic, sub in self.subs.items()]
        self.view = _ExecutorView(self.gate, self.executor, gated, [self.timer])
        self.view.created = {sub.handle.pointer: i for i, (sub, _) in enumerate(gated)}

    def plan(self, offered=None):
        """The plan of one executor wait offered ``offered`` gated subscriptions (all)."""
        offered = list(self.subs.values()) if offered is None else offered
        return self.gate.plan(self.view, [s.handle for s in offered])

    def arrive(self, *topics: str) -> None:
        """Messages arrived (the probe finds data) on these gated topics."""
        self.present |= {self.subs[t].handle.pointer for t in topics}

    def taken(self, *topics: str) -> None:
        """The executor took these messages (no data any more)."""
        self.present -= {self.subs[t].handle.pointer for t in topics}

    def ready(self) -> None:
        """Pass the discovery handshake."""
        self.plan()
        assert self.acks == [READY_TICK]


def pointers(handles) -> list[int]:
    return [h.pointer for h in handles]


def test_the_ready_ack_waits_for_every_gated_subscription_to_match_a_publisher():
    h = Harness()
    h.subs[B].publishers = 0
    plan = h.plan()
    assert h.acks == [] and plan.subs == [] and plan.cap_ns == cosim_gate._DISCOVERY_POLL_NS
    assert plan.hidden == h.view.gated_ptrs  # nothing is handed out before the handshake
    h.subs[B].publishers = 1
    h.plan()
    assert h.acks == [READY_TICK]
    h.plan()
    assert h.acks == [READY_TICK]  # once


def test_an_incomplete_bundle_hands_out_nothing_and_holds_no_acknowledgement():
    h = Harness()
    h.ready()
    h.arrive(CLOCK, A)  # b of tick 0 not here yet
    plan = h.plan()
    # only the missing one may wake the wait; none is ever handed out
    assert pointers(plan.subs) == [3] and plan.hidden == h.view.gated_ptrs
    assert h.acks == [READY_TICK]


def test_a_whole_bundle_is_released_one_callback_at_a_time_in_creation_order():
    h = Harness(executor=MultiThreadedExecutor())
    h.ready()
    h.arrive(CLOCK, A, B)
    order = []
    for expected in (1, 2, 3):
        plan = h.plan()
        assert pointers(plan.subs) == [expected]  # alone, clock first
        assert plan.hold_timers  # a timer of this tick waits for all its inputs
        assert plan.hidden == h.view.gated_ptrs - {expected}
        order.append(expected)
        h.taken({1: CLOCK, 2: A, 3: B}[expected])
    assert order == [1, 2, 3]
    plan = h.plan()
    assert h.acks == [READY_TICK, 0] and not plan.hold_timers


def test_nothing_is_released_while_a_callback_is_in_flight():
    h = Harness(executor=MultiThreadedExecutor())
    h.ready()
    h.arrive(CLOCK, A, B)
    assert pointers(h.plan().subs) == [1]
    h.taken(CLOCK)  # clock's callback was handed out and is still running
    h.executor.running(False)
    plan = h.plan()
    assert plan.subs == [] and plan.cap_ns is not None and plan.hold_timers
    assert plan.hidden == h.view.gated_ptrs
    h.executor.running(True)  # it finished: a is next
    assert pointers(h.plan().subs) == [2]


def test_the_view_sees_in_flight_tasks():
    h = Harness()
    assert not h.view.inflight()
    h.executor.running(True, False)
    assert h.view.inflight()
    h.executor.running(True, True)
    assert not h.view.inflight()


def test_the_ack_waits_for_callbacks_in_flight_and_ready_timers():
    h = Harness(executor=MultiThreadedExecutor())
    h.ready()
    h.arrive(CLOCK, A, B)
    for topic in (CLOCK, A, B):
        h.plan()
        h.taken(topic)
    h.executor.running(False)  # b's callback still runs
    plan = h.plan()
    assert h.acks == [READY_TICK] and plan.cap_ns is not None
    h.executor.running(True)
    h.timer.ready = True  # the tick's timer has not run yet
    h.plan()
    assert h.acks == [READY_TICK]
    h.timer.ready = False
    h.plan()
    assert h.acks == [READY_TICK, 0]


def test_a_single_threaded_executor_gets_a_whole_bundle_in_order_at_once():
    h = Harness()
    h.ready()
    h.arrive(CLOCK, A, B)
    assert pointers(h.plan().subs) == [1, 2, 3]  # one wait, the order it would run them in
    multi = Harness(executor=MultiThreadedExecutor())
    multi.ready()
    multi.arrive(CLOCK, A, B)
    assert pointers(multi.plan().subs) == [1]


def test_a_subscription_the_executor_left_out_is_not_released():
    h = Harness()
    h.ready()
    h.arrive(CLOCK, A, B)
    plan = h.plan(offered=[h.subs[A], h.subs[B]])  # clock's callback group is busy
    assert plan.subs == [] and plan.cap_ns is not None


def test_ticks_advance_by_the_period_and_bundles_follow_input_periods():
    h = Harness(inputs=[{"topic": "a"}, {"topic": "b", "period": 4, "phase": 0}], period=2)
    h.ready()
    assert h.gate.config.bundle(0) == {CLOCK, A, B}
    assert h.gate.config.bundle(2) == {CLOCK, A}
    h.arrive(CLOCK, A, B)
    for _ in range(3):
        h.plan()
    h.taken(CLOCK, A, B)
    h.plan()
    assert h.acks == [READY_TICK, 0]
    h.arrive(CLOCK, A)  # tick 2: b is not due
    for _ in range(2):
        h.plan()
    h.taken(CLOCK, A)
    h.plan()
    assert h.acks == [READY_TICK, 0, 2]


def test_a_delayed_input_is_not_awaited_before_its_first_tick():
    config = GateConfig.from_json('{"prefix": "/p/", "inputs": [{"topic": "a", "first": 1}]}')
    assert config.bundle(0) == {"/p/clock"} and config.bundle(1) == {"/p/clock", "/p/a"}


@pytest.mark.parametrize("raw,error", [
    ('{"prefix": "relative/"}', "absolute"),
    ('{"prefix": "/p/", "period": 0}', "period must be >= 1"),
    ('{"prefix": "/p/", "callback_order": "random"}', "callback_order"),
    ('{"prefix": "/p/", "inputs": ["/elsewhere/a"]}', "not below prefix"),
    ('{"prefix": "/p/", "inputs": [{"topic": "a", "period": 0}]}', "must be >= 1"),
])
def test_bad_configurations_are_refused(raw, error):
    with pytest.raises(ValueError, match=error):
        GateConfig.from_json(raw)
