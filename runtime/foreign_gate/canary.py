"""What the gate (``cosim_gate``) relies on inside rclpy, each checked against the installed
rclpy. These are internals, not API: a new rclpy may change any of them, and the gate
would then fail in ways far from the cause (a stalled tick, a start-deadline timeout).
``tests/test_gate_canary.py`` runs every check, so an upgrade names the one that changed.

Each check raises ``AssertionError`` saying what the gate expects and where it uses it.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable


def _executors_source() -> str:
    import rclpy.executors

    return inspect.getsource(rclpy.executors.Executor._wait_for_ready_callbacks)


def check_rclpy_proxy() -> None:
    """The executor builds its wait set as ``_rclpy.WaitSet(...)`` through the module global
    ``rclpy.executors._rclpy`` (the gate swaps that global for a proxy module), from
    ``Executor.wait_for_ready_callbacks`` (which the gate wraps to know the executor)."""
    import rclpy.executors

    rclpy_module = getattr(rclpy.executors, "_rclpy", None)
    assert rclpy_module is not None and hasattr(rclpy_module, "WaitSet"), (
        "rclpy.executors._rclpy (with WaitSet) is gone: _patch_executors has nothing to proxy")
    assert "_rclpy.WaitSet(" in _executors_source(), (
        "Executor._wait_for_ready_callbacks no longer builds _rclpy.WaitSet(...): the gate's "
        "WaitSet subclass would never be used")
    assert callable(getattr(rclpy.executors.Executor, "wait_for_ready_callbacks", None)), (
        "Executor.wait_for_ready_callbacks is gone: the gate cannot tell which executor waits")


def check_waitset_subclass() -> None:
    """The pybind ``WaitSet`` can be subclassed in Python and built with the positional
    arguments (subscriptions, guard conditions, timers, clients, services, events, context
    handle) that the executor and the gate's probe pass."""
    import rclpy
    from rclpy.impl.implementation_singleton import rclpy_implementation as real

    class Probe(real.WaitSet):
        pass

    context = rclpy.Context()
    context.init()
    try:
        with context.handle:
            wait_set = Probe(0, 1, 0, 0, 0, 0, context.handle)
            wait_set.clear_entities()
            wait_set.wait(0)
            ready = wait_set.get_ready_entities("subscription")
        assert list(ready) == [], f"a new wait set reports ready subscriptions: {ready}"
    finally:
        context.shutdown()


def check_add_order() -> None:
    """The executor adds subscriptions first, then clients, services, timers, guard
    conditions and waitables: the gate makes its plan at the first add after the
    subscriptions, before timers and events are added."""
    source = _executors_source()
    calls = ["add_subscription(", "add_client(", "add_service(", "add_timer(",
             "add_guard_condition(", "add_to_wait_set("]
    where = {call: source.find(call) for call in calls}
    missing = [call for call, at in where.items() if at < 0]
    assert not missing, f"_wait_for_ready_callbacks no longer calls {missing}"
    order = sorted(calls, key=where.get)
    assert order == calls, f"the executor now adds entities in the order {order}"


def check_tasks() -> None:
    """An executor keeps its in-flight callbacks in ``_tasks`` as (task, entity, node)
    triples under ``_tasks_lock``: the gate waits for them before releasing the next
    input of a tick."""
    import rclpy
    import rclpy.executors

    context = rclpy.Context()
    context.init()
    try:
        executor = rclpy.executors.SingleThreadedExecutor(context=context)
        with executor._tasks_lock:
            tasks = executor._tasks
        assert isinstance(tasks, list), f"Executor._tasks is a {type(tasks).__name__}"
        executor.shutdown()
    finally:
        context.shutdown()
    source = inspect.getsource(rclpy.executors)
    assert "self._tasks.append((task, entity, node))" in source, (
        "Executor no longer appends (task, entity, node) to _tasks: inflight() unpacks that")


def check_event_handle() -> None:
    """A QoS event handler keeps its rcl event as the name-mangled ``_EventHandler__event``
    (with ``pointer``): the gate mutes a gated subscription's events by that pointer."""
    import rclpy
    from rclpy.event_handler import QoSRequestedIncompatibleQoSInfo, SubscriptionEventCallbacks
    from std_msgs.msg import Int64

    def ignore(_info: QoSRequestedIncompatibleQoSInfo) -> None:
        return None

    context = rclpy.Context()
    context.init()
    try:
        node = rclpy.create_node("cosim_gate_canary", context=context)
        sub = node.create_subscription(Int64, "/cosim_gate_canary", lambda _m: None, 1,
                                       event_callbacks=SubscriptionEventCallbacks(
                                           incompatible_qos=ignore))
        handlers = list(getattr(sub, "event_handlers", ()))
        assert handlers, "Subscription.event_handlers is empty or gone"
        event = getattr(handlers[0], "_EventHandler__event", None)
        assert event is not None and hasattr(event, "pointer"), (
            "EventHandler no longer keeps its rcl event as self.__event with a pointer")
        node.destroy_node()
    finally:
        context.shutdown()


def check_multi_threaded() -> None:
    """A multi-threaded executor is recognised by its class name or its ``_executor``
    thread pool; a single-threaded one has neither (its callbacks may then be released
    several at a time)."""
    import rclpy
    import rclpy.executors

    context = rclpy.Context()
    context.init()
    try:
        multi = rclpy.executors.MultiThreadedExecutor(num_threads=2, context=context)
        single = rclpy.executors.SingleThreadedExecutor(context=context)
        assert type(multi).__name__ == "MultiThreadedExecutor"
        assert hasattr(multi, "_executor"), "MultiThreadedExecutor has no _executor pool"
        assert not hasattr(single, "_executor"), "SingleThreadedExecutor has an _executor"
        multi.shutdown()
        single.shutdown()
    finally:
        context.shutdown()


def check_time_source_qos() -> None:
    """rclpy's ``/clock`` subscription takes its reliability from the module global
    ``rclpy.time_source.ReliabilityPolicy.BEST_EFFORT``: the gate swaps that global for a
    shim whose BEST_EFFORT is RELIABLE (a lost clock would stall the lockstep)."""
    import rclpy.time_source as time_source

    policy = getattr(time_source, "ReliabilityPolicy", None)
    assert policy is not None and {"BEST_EFFORT", "RELIABLE"} <= {m.name for m in policy}, (
        "rclpy.time_source.ReliabilityPolicy (an enum with BEST_EFFORT, RELIABLE) is gone")
    source = inspect.getsource(time_source.TimeSource._subscribe_to_clock_topic)
    assert "ReliabilityPolicy.BEST_EFFORT" in source, (
        "TimeSource._subscribe_to_clock_topic no longer uses ReliabilityPolicy.BEST_EFFORT")


CHECKS: dict[str, Callable[[], None]] = {
    "executors._rclpy proxy": check_rclpy_proxy,
    "WaitSet subclass and its positional arguments": check_waitset_subclass,
    "the order the executor adds entities": check_add_order,
    "_tasks_lock and _tasks": check_tasks,
    "_EventHandler__event": check_event_handle,
    "how a multi-threaded executor is recognised": check_multi_threaded,
    "the time_source QoS shim": check_time_source_qos,
}
"""The rclpy internals the gate depends on, by name."""
