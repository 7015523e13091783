"""Lockstep input gate for foreign rclpy programs run under cosim.

The orchestrator ("feeder") remaps a foreign program's input topics and its
``/clock`` onto private topics below a prefix (``/cosim/feed/<node>/``) and,
for every tick ``j`` the program is due at, publishes one message on each
input scheduled at ``j`` followed by the ``Clock`` of tick ``j``.  It only
publishes tick ``j + period`` once the program acknowledged, on
``<prefix>taken`` (``std_msgs/Int64MultiArray``, reliable, transient-local, depth
1000: the program's consumers read it too), that it has taken and processed tick ``j``:
``[j, n_1, ..., n_m]``, where ``n_i`` is how many messages the program published on its i-th
output (``outputs`` in the configuration) since the previous acknowledgement, from
callbacks and timers alike: zero, one or several, so consumers know which messages belong
to tick ``j`` without counting on a fixed number.

This module makes an unmodified rclpy program honour that protocol; the RMW gate
(``runtime/rmw_gate/rmw_cosim_gate.c``) honours the same one for any program on rcl, at
the middleware layer.  It is
injected through ``sitecustomize`` (see ``sitecustomize.py`` next to it) and
changes nothing in the program's code.  It works at the level of the wait set
that :meth:`rclpy.executors.Executor._wait_for_ready_callbacks` builds on every
iteration: ``rclpy.executors._rclpy`` is replaced by a proxy module whose
``WaitSet`` is a Python subclass of the real pybind ``WaitSet`` (so C++
waitables still get a genuine ``WaitSet``).  The subclass

* collects the *gated* subscriptions (topic below the prefix) instead of
  adding them, and asks the gate for a plan as soon as the executor adds
  anything else; the plan says which gated subscriptions go into this wait,
  whether the program's timers are withheld, and which QoS event handlers of
  gated subscriptions are withheld (they share the DDS reader's status
  condition with the data, and would otherwise wake the wait in a loop);
* filters gated subscriptions that were only added to be woken up out of
  ``get_ready_entities('subscription')``, so the executor never yields them.

Per executor wait the gate (all in the executor's own thread, no extra thread):

1. probes, on a private wait set with timeout 0, which gated subscriptions
   hold data;
2. while bundle ``j`` is incomplete, lets gated subscriptions without data
   wake the executor (it then finds nothing to run and rebuilds its wait
   set) but never hands them out, so no callback sees part of a tick;
3. once every topic of bundle ``j`` has data, releases them ONE AT A TIME in
   the order a ``SingleThreadedExecutor`` would run them (executor node order,
   then ``node.subscriptions`` creation order; the sim-time ``/clock``
   subscription is created by ``Node.__init__`` and so comes first), each only
   when no callback of the executor is in flight.  While the bundle is partly
   taken, the program's timers are withheld, so a sim-time timer made ready
   by the new clock cannot run before the inputs of its tick.  Serialising the
   gated callbacks gives the same order on a ``MultiThreadedExecutor``
   (whatever its callback groups are) as on a ``SingleThreadedExecutor``;
4. when all of bundle ``j`` has been taken, no task of the executor is in
   flight and none of the program's timers is ready any more (so timers due
   at tick ``j`` have run), publishes the acknowledgement ``j``.

Before the first tick the gate publishes ``[-1]`` on the ack topic once each of
its gated subscriptions has matched a publisher ("ready"), so the feeder knows
that nothing it publishes can be lost to discovery.  With ``readers`` configured
it also says, as ``[-1, 1]`` (instead of ``[-1]``, or after it, before the first
tick's ack), that every output has a publisher matching at least that many
subscriptions, so the feeder knows that nothing the program publishes can be lost
to discovery either, and need not wait a settle time for it.

Configuration comes from the ``COSIM_GATE`` environment variable (JSON)::

    {"prefix": "/cosim/feed/ctl/",   # private topic prefix (absolute)
     "node": "ctl",                  # cosim name of the program (naming only)
     "tick_ns": 10000000,            # duration of one tick (or "20000000/3")
     "period": 1,                    # program fed at ticks start + k*period
     "start": 0,                     # first tick fed
     "inputs": [                     # gated inputs, relative to prefix
        {"topic": "odom"},                          # due at every fed tick
        {"topic": "scan", "period": 5, "phase": 0}  # due at j % 5 == 0
     ],
     "outputs": ["/cmd_vel"],        # output topics (resolved names) counted per tick
     "readers": [2],                 # optional: subscriptions each output will have
     "callback_order": "subscription",  # or "inputs" (see below)
     "reliable_clock": true}         # make rclpy's /clock subscription reliable

Fed subscriptions are made reliable whatever QoS the program asks for (a best-effort
reader, e.g. ``qos_profile_sensor_data``, could lose a fed message), and a node that runs
with ``use_sim_time`` false while it subscribes to fed inputs stops the program with an
error naming it (its timers and ``now()`` would follow the wall clock, not the run).

``bundle(j)`` is ``{prefix + "clock"}`` plus every input with
``(j - phase) % period == 0`` (input period defaults to the program's period,
phase to ``start``).  Gated topics the program never subscribed to are
ignored.  ``callback_order`` picks the order in which a bundle's callbacks
run: ``"subscription"`` (default) is the order a SingleThreadedExecutor uses
when all messages are ready at once (node order, then subscription creation
order, which puts the sim-time clock first); ``"inputs"`` is clock first, then
the order of ``inputs`` in the configuration, whatever the program's code.
"""

from __future__ import annotations

import contextlib
import json
import threading
import types
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

ENV_VAR = 'COSIM_GATE'
READY_TICK = -1

# Poll interval bounds used only while the gate waits for an in-flight
# callback of a MultiThreadedExecutor to finish (no rcl event signals the
# completion of a Task).
_POLL_MIN_NS = 200_000
_POLL_MAX_NS = 5_000_000
# Poll interval while waiting for discovery before the first tick.
_DISCOVERY_POLL_NS = 20_000_000


@dataclass(frozen=True)
class InputSpec:
    """Schedule of one gated input topic."""

    topic: str
    period: int
    phase: int
    first: int = 0  # no sample before this tick (a delayed input has none at tick 0)


@dataclass(frozen=True)
class GateConfig:
    """Parsed ``COSIM_GATE`` configuration."""

    prefix: str
    node: str
    tick_ns: int | Fraction  # exact; a Fraction where not whole ns (30 Hz with 50 Hz)
    period: int
    start: int
    inputs: tuple[InputSpec, ...]
    reliable_clock: bool = True
    callback_order: str = 'subscription'
    outputs: tuple[str, ...] = ()
    # per output, the subscriptions its publisher must match before the gate says so
    readers: tuple[int, ...] = ()

    @property
    def clock_topic(self) -> str:
        """The program's fed /clock."""
        return self.prefix + 'clock'

    @property
    def ack_topic(self) -> str:
        """Where the gate acknowledges each bundle taken."""
        return self.prefix + 'taken'

    def bundle(self, tick: int) -> frozenset[str]:
        """Return the gated topics that must be delivered at ``tick``."""
        topics = {self.clock_topic}
        for spec in self.inputs:
            if tick >= spec.first and (tick - spec.phase) % spec.period == 0:
                topics.add(spec.topic)
        return frozenset(topics)

    @classmethod
    def from_json(cls, text: str) -> GateConfig:
        """Parse and check the ``COSIM_GATE`` JSON."""
        raw = json.loads(text)
        prefix = raw['prefix']
        if not prefix.startswith('/'):
            raise ValueError('prefix must be absolute')
        if not prefix.endswith('/'):
            prefix += '/'
        period = int(raw.get('period', 1))
        start = int(raw.get('start', 0))
        if period < 1:
            raise ValueError('period must be >= 1')
        order = raw.get('callback_order', 'subscription')
        if order not in ('subscription', 'inputs'):
            raise ValueError('callback_order must be "subscription" or "inputs"')
        if raw.get('readers') and len(raw['readers']) != len(raw.get('outputs', ())):
            raise ValueError('readers must name one count per output')
        inputs = []
        for item in raw.get('inputs', []):
            if isinstance(item, str):
                item = {'topic': item}
            topic = item['topic']
            if not topic.startswith('/'):
                topic = prefix + topic
            if not topic.startswith(prefix):
                raise ValueError(f'input {topic!r} is not below prefix {prefix!r}')
            ip = int(item.get('period', period))
            if ip < 1:
                raise ValueError(f'period of {topic!r} must be >= 1')
            inputs.append(InputSpec(topic, ip, int(item.get('phase', start)),
                                    int(item.get('first', 0))))
        return cls(prefix=prefix, node=str(raw.get('node', 'program')),
                   tick_ns=Fraction(str(raw.get('tick_ns', 0))), period=period, start=start,
                   inputs=tuple(inputs),
                   reliable_clock=bool(raw.get('reliable_clock', True)),
                   callback_order=order,
                   outputs=tuple(str(t) for t in raw.get('outputs', ())),
                   readers=tuple(int(n) for n in raw.get('readers', ())))


class _Plan:
    """What one executor wait may contain (result of :meth:`Gate.plan`)."""

    __slots__ = ('subs', 'hold_timers', 'hidden', 'muted', 'cap_ns')

    def __init__(self) -> None:
        self.subs: list[object] = []       # gated subscription handles to add
        self.hold_timers = False           # keep the program's timers out
        self.hidden: frozenset[int] = frozenset()  # gated sub pointers never handed out
        self.muted: frozenset[int] = frozenset()   # gated sub pointers whose events stay out
        self.cap_ns: int | None = None  # upper bound on the wait's timeout


class Gate:
    """Process-wide gate state; one bundle sequence per foreign program."""

    def __init__(self, config: GateConfig) -> None:
        self.config = config
        self._lock = threading.RLock()
        self._tick = config.start
        self._released = False
        self._ready_sent = False
        # whether the program's output publishers are known to match their readers
        # (``readers``): told once, as ``[-1, 1]``, before the first tick's ack
        self._outputs_told = not config.readers
        self._poll_ns = _POLL_MIN_NS
        self._topic_cache: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self._ack_node = None
        self._ack_pub = None
        self._ack_msg_type = None
        self._real_rclpy = None
        self._probe_key = None
        self._probe_gc = None
        self._probe_ws = None
        self._counts = [0] * len(config.outputs)  # messages per output since the last ack
        self._output_of: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self._sim_time_checked: set[int] = set()

    # ----------------------------------------------------------------- outputs
    def published(self, publisher) -> None:
        """Count one message the program publishes (on a declared output)."""
        try:
            index = self._output_of[publisher]
        except KeyError:
            try:
                name = publisher.topic_name
            except Exception:  # being destroyed: not one of ours to count
                return
            outputs = self.config.outputs
            index = self._output_of[publisher] = \
                outputs.index(name) if name in outputs else None
        if index is not None:
            with self._lock:
                self._counts[index] += 1

    def check_sim_time(self, nodes) -> None:
        """Stop the program if a node with fed inputs runs on the wall clock."""
        for node in nodes:
            if id(node) in self._sim_time_checked:
                continue
            try:
                sim = node.get_parameter('use_sim_time').value
            except Exception:  # no such parameter: not a node with a time source
                sim = True
            if not sim:
                import os
                import sys
                print(f'cosim gate: fatal: node {node.get_name()!r} of foreign program '
                      f'{self.config.node!r} runs with use_sim_time false, so its timers and '
                      'now() would follow the wall clock, not the run. cosim starts every '
                      'foreign program with use_sim_time:=true: remove what sets it to false '
                      '(a parameter_overrides entry, a parameter file, set_parameters).',
                      file=sys.stderr, flush=True)
                os._exit(78)
            self._sim_time_checked.add(id(node))

    # ----------------------------------------------------------------- view
    def _topic_of(self, sub) -> str:
        try:
            return self._topic_cache[sub]
        except KeyError:
            name = sub.topic_name
            self._topic_cache[sub] = name
            return name

    def view(self, executor) -> _ExecutorView | None:
        """Snapshot the gated subscriptions and timers of ``executor``'s nodes.

        Returns ``None`` when the executor has no gated subscription, in which
        case its wait sets are left completely alone.
        """
        if not executor.context.ok():
            return None  # shutting down: leave the wait set alone
        prefix = self.config.prefix
        gated: list[tuple[object, str]] = []
        timers: list[object] = []
        fed_nodes = []
        for node in executor.get_nodes():
            fed = False
            for sub in node.subscriptions:
                topic = self._topic_of(sub)
                if topic.startswith(prefix):
                    gated.append((sub, topic))
                    fed = True
            timers.extend(node.timers)
            if fed:
                fed_nodes.append(node)
        if not gated:
            return None
        self.check_sim_time(fed_nodes)
        created = {sub.handle.pointer: i for i, (sub, _) in enumerate(gated)}
        if self.config.callback_order == 'inputs':
            rank = {spec.topic: i for i, spec in enumerate(self.config.inputs, 1)}
            rank[self.config.clock_topic] = 0
            gated.sort(key=lambda item: rank.get(item[1], len(rank)))  # stable
        view = _ExecutorView(self, executor, gated, timers)
        view.created = created
        return view

    # ----------------------------------------------------------------- acks
    def _ensure_ack_publisher(self, context) -> None:
        if self._ack_pub is not None:
            return
        from rclpy.node import Node
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import Int64MultiArray
        name = '_cosim_gate_' + ''.join(c if c.isalnum() else '_' for c in self.config.node)
        self._ack_node = Node(name, context=context, use_global_arguments=False,
                              enable_rosout=False, start_parameter_services=False)
        # deep enough for a consumer that lags the program by the pipeline window
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._ack_msg_type = Int64MultiArray
        self._ack_pub = self._ack_node.create_publisher(Int64MultiArray,
                                                        self.config.ack_topic, qos)

    def _ack(self, tick: int, outputs_matched: bool = False) -> None:
        msg = self._ack_msg_type()
        if tick == READY_TICK:
            msg.data = [READY_TICK, 1] if outputs_matched else [READY_TICK]
        else:
            msg.data = [tick, *self._counts]
            self._counts = [0] * len(self._counts)
        self._ack_pub.publish(msg)

    def _outputs_matched(self, view: _ExecutorView) -> bool:
        """Whether every declared output has a publisher, and each publisher of one matches
        at least the readers the configuration names (its consumers and the orchestrator):
        what it publishes from now on reaches them all."""
        want = dict(zip(self.config.outputs, self.config.readers, strict=True))
        seen = set()
        for node in view.executor.get_nodes():
            for pub in node.publishers:
                try:
                    topic = pub.topic_name
                    if topic in want and pub.get_subscription_count() < want[topic]:
                        return False
                except Exception:  # being destroyed: not one to wait for
                    continue
                seen.add(topic)
        return seen >= set(want)

    def _tell_outputs(self, view: _ExecutorView, plan: _Plan) -> None:
        """Before the first tick's ack: say once that the outputs match their readers, so
        the orchestrator need not wait out a settle time for them; until then, look again
        at least every discovery poll."""
        if self._outputs_matched(view):
            self._outputs_told = True
            self._ack(READY_TICK, outputs_matched=True)
        else:
            plan.cap_ns = _DISCOVERY_POLL_NS

    # ----------------------------------------------------------------- probe
    def _probe(self, view: _ExecutorView) -> frozenset[int]:
        """Pointers of the gated subscriptions that currently hold data.

        Waits, with timeout 0, on a private wait set holding the gated
        subscriptions plus a guard condition triggered just before: the wait
        returns at once and reports every subscription with data (rcl_wait
        semantics).  With rmw_fastrtps the triggered guard also makes rmw_wait
        skip attaching/detaching conditions to a DDS wait set, which cuts
        the probe from ~70 us to ~5 us.
        """
        r = self._real_rclpy
        with contextlib.ExitStack() as stack:
            handles = []
            for sub, _ in view.gated:
                try:
                    stack.enter_context(sub.handle)
                    handles.append(sub.handle)
                except Exception:  # InvalidHandle: being destroyed
                    pass
            if not handles:
                return frozenset()
            context = view.executor.context
            stack.enter_context(context.handle)
            key = (id(context), len(handles))
            if self._probe_key != key:
                self._probe_gc = r.GuardCondition(context.handle)
                self._probe_ws = r.WaitSet(len(handles), 1, 0, 0, 0, 0, context.handle)
                self._probe_key = key
            ws = self._probe_ws
            self._probe_gc.trigger_guard_condition()
            ws.clear_entities()
            for h in handles:
                ws.add_subscription(h)
            ws.add_guard_condition(self._probe_gc)
            ws.wait(0)
            return frozenset(ws.get_ready_entities('subscription'))

    # ----------------------------------------------------------------- plan
    def plan(self, view: _ExecutorView, offered_subs: Sequence[object]) -> _Plan:
        """Decide what the executor's next wait may contain; ack if due.

        ``offered_subs`` are the gated subscription handles the executor put
        into its wait set (it leaves out those whose callback group is busy
        or whose previous message is still being handled).
        """
        with self._lock:
            return self._plan_locked(view, offered_subs)

    def _plan_locked(self, view, offered_subs) -> _Plan:
        cfg = self.config
        plan = _Plan()
        gated_ptrs = view.gated_ptrs
        plan.hidden = gated_ptrs
        self._ensure_ack_publisher(view.executor.context)

        if not self._ready_sent:
            # Handshake: every gated subscription must see the feeder's
            # publisher before the feeder may send tick `start`.
            if all(sub.get_publisher_count() > 0 for sub, _ in view.gated):
                self._ready_sent = True
                if not self._outputs_told and self._outputs_matched(view):
                    self._outputs_told = True
                    self._ack(READY_TICK, outputs_matched=True)
                else:
                    self._ack(READY_TICK)
            else:
                plan.cap_ns = _DISCOVERY_POLL_NS
                return plan
        if not self._outputs_told:
            if self._tick != cfg.start or self._released:
                self._outputs_told = True  # fed already: the orchestrator did not need it
            else:
                self._tell_outputs(view, plan)

        present = self._probe(view)
        # Events (QoS event handlers) of a gated subscription share the DDS
        # reader's status condition with its data: with the data withheld
        # they would wake the wait set at once, over and over.
        plan.muted = present
        inflight = view.inflight()
        while True:
            bundle = cfg.bundle(self._tick)
            due = [sub for sub, topic in view.gated if topic in bundle]
            if not self._released:
                # `due` is empty only if the program subscribed to none of the
                # bundle's topics (e.g. no use_sim_time): nothing to gate.
                if due and all(sub.handle.pointer in present for sub in due):
                    self._released = True
                else:
                    # Incomplete: let missing gated data wake us, hand out nothing.
                    plan.subs = [h for h in offered_subs if h.pointer not in present]
                    return plan
            pending = [sub for sub in due if sub.handle.pointer in present]
            if pending:
                # Bundle partly taken: hand out the next one, alone, once idle;
                # program timers stay out until the whole bundle is taken.
                plan.hold_timers = True
                batch = self._batch(view, pending, offered_subs)
                if not inflight and batch:
                    released = {h.pointer for h in batch}
                    plan.subs = batch
                    plan.hidden = gated_ptrs - released
                    plan.muted = present - released
                    self._poll_ns = _POLL_MIN_NS
                else:
                    plan.cap_ns = self._next_poll()
                return plan
            # Whole bundle taken.  Ack once every callback it triggered has run.
            if inflight or view.timer_ready():
                if inflight:
                    plan.cap_ns = self._next_poll()
                return plan
            self._ack(self._tick)
            self._tick += cfg.period
            self._released = False
            self._poll_ns = _POLL_MIN_NS

    @staticmethod
    def _batch(view, pending, offered_subs) -> list:
        """The handles to release in one wait: the next pending one, and, on an executor
        that runs one wait's callbacks one after another in subscription creation order
        (not a MultiThreadedExecutor), the following ones as long as that order is the
        wanted order too: fewer executor loops per tick, the same callback order."""
        offered = {h.pointer for h in offered_subs}
        batch = []
        for sub in pending:
            ptr = sub.handle.pointer
            if ptr not in offered:
                break
            if batch and not (view.sequential
                              and view.created[ptr] > view.created[batch[-1].pointer]):
                break
            batch.append(sub.handle)
        return batch

    def _next_poll(self) -> int:
        ns = self._poll_ns
        self._poll_ns = min(ns * 2, _POLL_MAX_NS)
        return ns


class _ExecutorView:
    """Gated subscriptions and timers of one executor at one wait."""

    __slots__ = ('gate', 'executor', 'gated', 'timers', 'timer_ptrs', 'gated_ptrs',
                 'event_owner', 'created', 'sequential')

    def __init__(self, gate: Gate, executor, gated, timers) -> None:
        self.gate = gate
        self.executor = executor
        self.gated = gated
        self.timers = timers
        self.gated_ptrs = frozenset(sub.handle.pointer for sub, _ in gated)
        self.created: dict[int, int] = {}  # subscription pointer -> creation order
        # one wait's callbacks run one at a time, in creation order (not multi-threaded)
        self.sequential = type(executor).__name__ != 'MultiThreadedExecutor' \
            and not hasattr(executor, '_executor')
        self.timer_ptrs = frozenset(t.handle.pointer for t in timers)
        # rcl event handle pointer -> pointer of the gated subscription owning it
        self.event_owner: dict[int, int] = {}
        for sub, _ in gated:
            for handler in getattr(sub, 'event_handlers', ()):
                event = getattr(handler, '_EventHandler__event', None)
                if event is not None:
                    self.event_owner[event.pointer] = sub.handle.pointer

    def inflight(self) -> bool:
        """True while a task (callback) of the executor has not finished."""
        ex = self.executor
        with ex._tasks_lock:
            return any(not task.done() for task, _, _ in ex._tasks)

    def timer_ready(self) -> bool:
        """True while one of the program's timers is due but has not run."""
        for tmr in self.timers:
            try:
                with tmr.handle:
                    if tmr.handle.is_timer_ready():
                        return True
            except Exception:  # InvalidHandle: destroyed timer
                continue
        return False


# --------------------------------------------------------------------------
# rclpy integration
# --------------------------------------------------------------------------

_gate: Gate | None = None
_current = threading.local()


def _make_waitset_class(real_waitset):
    class GatedWaitSet(real_waitset):
        """A real ``_rclpy.WaitSet`` whose gated entries the gate controls.

        The executor adds subscriptions first, then clients, services,
        timers, guard conditions and waitables (executors.py, in
        ``_wait_for_ready_callbacks``).  Gated subscriptions are collected;
        the gate's plan is made at the first add of anything else (or at
        ``wait``), so that it is known before timers and events are added.
        """

        def __init__(self, *args) -> None:
            super().__init__(*args)
            view = None
            executor = getattr(_current, 'executor', None)
            if executor is not None and _gate is not None:
                view = _gate.view(executor)
            self._cosim_view = view
            self._cosim_subs: list[object] = []
            self._cosim_plan: _Plan | None = None

        def _cosim_ensure_plan(self) -> _Plan | None:
            plan = self._cosim_plan
            if plan is None and self._cosim_view is not None:
                view = self._cosim_view
                plan = self._cosim_plan = view.gate.plan(view, self._cosim_subs)
                for h in plan.subs:
                    super().add_subscription(h)
            return plan

        def add_subscription(self, handle):
            view = self._cosim_view
            if view is not None and handle.pointer in view.gated_ptrs:
                if self._cosim_plan is None:
                    self._cosim_subs.append(handle)
                return None
            return super().add_subscription(handle)

        def add_timer(self, handle):
            plan = self._cosim_ensure_plan()
            if plan is not None and plan.hold_timers and \
                    handle.pointer in self._cosim_view.timer_ptrs:
                return None
            return super().add_timer(handle)

        def add_event(self, handle):
            plan = self._cosim_ensure_plan()
            if plan is not None and \
                    self._cosim_view.event_owner.get(handle.pointer) in plan.muted:
                return None
            return super().add_event(handle)

        def add_client(self, handle):
            self._cosim_ensure_plan()
            return super().add_client(handle)

        def add_service(self, handle):
            self._cosim_ensure_plan()
            return super().add_service(handle)

        def add_guard_condition(self, handle):
            self._cosim_ensure_plan()
            return super().add_guard_condition(handle)

        def wait(self, timeout_nsec):
            plan = self._cosim_ensure_plan()
            if plan is not None and plan.cap_ns is not None and \
                    (timeout_nsec < 0 or timeout_nsec > plan.cap_ns):
                timeout_nsec = plan.cap_ns
            return super().wait(timeout_nsec)

        def get_ready_entities(self, entity_type):
            ready = super().get_ready_entities(entity_type)
            plan = self._cosim_plan
            if entity_type == 'subscription' and plan is not None and plan.hidden:
                hidden = plan.hidden
                ready = [p for p in ready if p not in hidden]
            return ready

    return GatedWaitSet


def _patch_executors(executors_module) -> None:
    """Install the gate into an imported ``rclpy.executors`` module."""
    real = executors_module._rclpy
    if getattr(real, '_cosim_gate_proxy', False):
        return
    _gate._real_rclpy = real
    proxy = types.ModuleType(real.__name__ + '_cosim_gate')
    proxy.__dict__.update(real.__dict__)
    proxy.WaitSet = _make_waitset_class(real.WaitSet)
    proxy._cosim_gate_proxy = True
    executors_module._rclpy = proxy

    executor_cls = executors_module.Executor
    original = executor_cls.wait_for_ready_callbacks

    def wait_for_ready_callbacks(self, *args, **kwargs):
        previous = getattr(_current, 'executor', None)
        _current.executor = self
        try:
            return original(self, *args, **kwargs)
        finally:
            _current.executor = previous

    wait_for_ready_callbacks.__doc__ = original.__doc__
    wait_for_ready_callbacks.__wrapped__ = original
    executor_cls.wait_for_ready_callbacks = wait_for_ready_callbacks


def _patch_publisher(publisher_module) -> None:
    """Count what the program publishes, per declared output, for the tick's ack."""
    cls = publisher_module.Publisher
    original = cls.publish

    def publish(self, msg):
        original(self, msg)
        if _gate is not None:
            _gate.published(self)

    publish.__doc__ = original.__doc__
    publish.__wrapped__ = original
    cls.publish = publish


def _patch_node(node_module) -> None:
    """Fed subscriptions are reliable and volatile, whatever QoS the program asks for: a
    best-effort reader (sensor-data QoS) could lose a fed message, and a transient-local
    one would not match the feeder."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    cls = node_module.Node
    original = cls.create_subscription

    def create_subscription(self, msg_type, topic, callback, qos_profile, **kwargs):
        try:
            fed = self.resolve_topic_name(topic).startswith(_gate.config.prefix)
        except Exception:  # an invalid name: let rclpy report it
            fed = False
        if fed:
            if isinstance(qos_profile, int):
                qos_profile = QoSProfile(depth=qos_profile)
            keep_all = qos_profile.history == HistoryPolicy.KEEP_ALL
            qos_profile = QoSProfile(
                history=qos_profile.history,
                depth=qos_profile.depth if keep_all else max(qos_profile.depth, 1),
                reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.VOLATILE)
        return original(self, msg_type, topic, callback, qos_profile, **kwargs)

    create_subscription.__doc__ = original.__doc__
    create_subscription.__wrapped__ = original
    cls.create_subscription = create_subscription


def _patch_time_source(time_source_module) -> None:
    """Make rclpy's ``/clock`` subscription reliable (feeder publishes reliable).

    ``TimeSource._subscribe_to_clock_topic`` hard-codes BEST_EFFORT; a lost
    clock message would stall the lockstep forever.
    """
    real = time_source_module.ReliabilityPolicy
    shim = types.SimpleNamespace(**{m.name: m for m in real})
    shim.BEST_EFFORT = real.RELIABLE
    time_source_module.ReliabilityPolicy = shim


EXIT_UNSUPPORTED = 78  # as sitecustomize's exit when the gate cannot be installed


def _refuse_events_executor(events_module) -> None:
    """rclpy's ``EventsExecutor`` (``rclpy.experimental``) waits in C++, on no wait set of
    ``rclpy.executors``: the gate never sees it, so a program using it would take no tick
    and the run would only end at its start deadline. Name it when the program makes one."""
    def refused(*_args, **_kwargs):
        import os
        import sys
        print("cosim gate: fatal: this program uses rclpy's EventsExecutor "
              "(rclpy.experimental), which waits without an rclpy wait set, so the cosim gate "
              "cannot hold its inputs to the lockstep; use rclpy.executors."
              "SingleThreadedExecutor or MultiThreadedExecutor (rclpy.spin uses the first).",
              file=sys.stderr, flush=True)
        os._exit(EXIT_UNSUPPORTED)

    events_module.EventsExecutor = refused


def install(config: GateConfig) -> None:
    """Arrange for rclpy to be gated when (or if) the program imports it."""
    global _gate
    if _gate is not None:
        return
    _gate = Gate(config)
    hooks = {'rclpy.executors': _patch_executors, 'rclpy.publisher': _patch_publisher,
             'rclpy.node': _patch_node,
             'rclpy.experimental.events_executor': _refuse_events_executor}
    if config.reliable_clock:
        hooks['rclpy.time_source'] = _patch_time_source
    import sys
    for name, hook in list(hooks.items()):
        module = sys.modules.get(name)
        if module is not None:
            hook(module)
            del hooks[name]
    if hooks:
        sys.meta_path.insert(0, _PostImportFinder(hooks))


class _PostImportFinder:
    """Meta-path finder that runs a hook right after a module is executed."""

    def __init__(self, hooks) -> None:
        self._hooks = dict(hooks)
        self._busy = set()

    def find_spec(self, fullname, path, target=None):
        hook = self._hooks.get(fullname)
        if hook is None or fullname in self._busy:
            return None
        import importlib.util
        self._busy.add(fullname)
        try:
            spec = importlib.util.find_spec(fullname)
        finally:
            self._busy.discard(fullname)
        if spec is None or spec.loader is None or not hasattr(spec.loader, 'exec_module'):
            return None
        loader = spec.loader
        original_exec = loader.exec_module

        def exec_module(module):
            original_exec(module)
            del self._hooks[fullname]
            hook(module)

        loader.exec_module = exec_module
        return spec


def install_from_env(environ=None) -> bool:
    """Install the gate if ``COSIM_GATE`` is set; remove it from ``environ``.

    The variable is removed so that child processes of the program are not
    gated with the program's configuration.
    """
    import os
    env = os.environ if environ is None else environ
    text = env.pop(ENV_VAR, None)
    if not text:
        return False
    install(GateConfig.from_json(text))
    return True
