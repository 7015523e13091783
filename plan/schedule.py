"""The schedule: a pure function of the scenario saying who acts when and on which samples.

Time is counted in ticks; ``tick_ns`` is exact (an int, or a Fraction such as 1/150 s for
30 Hz with 50 Hz) and tick ``k`` is at ``time_ns(k)``, ``k * tick_ns`` rounded to whole
nanoseconds once (``plan.timeutil.tick_time_ns``). A node with a period of
``p`` ticks acts at every ``k`` with ``k % p == 0``. An input edge is ``same_tick`` (the
consumer waits for the producer's sample at or before ``k``) or ``delayed`` (the latest
sample strictly before ``k``: a zero-order hold that breaks algebraic loops). A topic may
have a period of its own (``topic_periods``), a multiple of its producer's: it is published
only at the producer's activations at multiples of it (a controller manager run in the
physics step at physics' rate / n publishes its controllers' topics every n-th activation),
as a topic with a window is published only inside it.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass
from fractions import Fraction
from functools import cached_property

from plan.timeutil import Ns, tick_at_ns, tick_time_ns

SAME_TICK = "same_tick"
DELAYED = "delayed"


@dataclass(frozen=True)
class Edge:
    """Consumer reads ``topic``, published by producer, with the given mode."""

    consumer: str
    producer: str
    topic: str
    mode: str


class CycleError(ValueError):
    """A cycle of same_tick edges: an algebraic loop with no delay to break it."""

    def __init__(self, cycle: list[str]):
        self.cycle = cycle
        super().__init__(" -> ".join(cycle))


def find_same_tick_cycle(nodes: list[str], edges: list[Edge]) -> list[str] | None:
    """A cycle of same_tick edges as [a, b, ..., a], or None (depth-first, deterministic).

    Iterative, so a long chain of nodes cannot exhaust Python's recursion limit.
    """
    succ: dict[str, list[str]] = {n: [] for n in nodes}
    for e in edges:
        if e.mode == SAME_TICK:
            for end in (e.producer, e.consumer):
                if end not in succ:
                    raise ValueError(f"edge {e.producer} -> {e.consumer} ({e.topic}) names "
                                     f"unknown node {end!r}")
            succ[e.producer].append(e.consumer)
    state: dict[str, int] = {}  # 1 = on the stack, 2 = done
    for root in sorted(succ):
        if root in state:
            continue
        stack: list[str] = [root]
        todo = [iter(sorted(set(succ[root])))]
        state[root] = 1
        while todo:
            m = next(todo[-1], None)
            if m is None:
                state[stack.pop()] = 2
                todo.pop()
            elif state.get(m) == 1:
                return stack[stack.index(m):] + [m]
            elif m not in state:
                state[m] = 1
                stack.append(m)
                todo.append(iter(sorted(set(succ[m]))))
    return None


def _is_int(value: object) -> bool:
    """A true int: time is integer nanoseconds and ticks, never float (and never bool)."""
    return isinstance(value, int) and not isinstance(value, bool)


# How many ticks /clock may run ahead of the oldest tick a node still owes. Nodes wait for
# the exact samples the schedule names, so this changes when work happens, never what it
# computes; it lets a producer's next ticks overlap its consumers' current one and batches
# the wake-ups of every process (measured in bench/README.md).
PIPELINE_WINDOW = 16


Window = tuple[int, int | None]  # [start, end) in ticks; end None: to the run's end
NEVER = 1 << 62  # the start of a window not opened yet (a robot a client may bring in)


def first_activation(period: int, start: int) -> int:
    """The first activation at or after tick ``start`` of a node acting every ``period``
    ticks (its first in a window that starts at ``start``)."""
    return -(-start // period) * period


class Schedule:
    """Who acts at each tick, in which order, and which producer tick each input consumes."""

    def __init__(self, tick_ns: Ns, last_tick: int, periods: dict[str, int], edges: list[Edge],
                 windows: dict[str, Window] | None = None,
                 topic_windows: dict[str, Window] | None = None,
                 topic_periods: dict[str, int] | None = None,
                 input_periods: dict[tuple[str, str], int] | None = None):
        if (not (_is_int(tick_ns) or isinstance(tick_ns, Fraction)) or not _is_int(last_tick)
                or tick_ns <= 0 or last_tick < 0):
            raise ValueError("tick_ns must be a positive int or Fraction and last_tick a "
                             "non-negative int")
        for name, period in periods.items():
            if not _is_int(period) or period <= 0:
                raise ValueError(f"period of {name} must be a positive whole number of ticks")
        self.tick_ns = tick_ns
        self.last_tick = last_tick
        self.periods = dict(periods)
        self.edges = list(edges)
        for e in self.edges:
            if e.producer not in self.periods or e.consumer not in self.periods:
                raise ValueError(f"edge {e.producer} -> {e.consumer} ({e.topic}) names a node "
                                 "that has no period")
            if e.mode not in (SAME_TICK, DELAYED):
                raise ValueError(f"edge mode {e.mode!r} is not {SAME_TICK} or {DELAYED}")
        if cycle := find_same_tick_cycle(list(periods), self.edges):
            raise CycleError(cycle)
        self.order = self._topological_order()
        self.inputs_of: dict[str, list[Edge]] = {n: [] for n in periods}
        for e in self.edges:
            self.inputs_of[e.consumer].append(e)
        self.windows = dict(windows or {})  # node -> the ticks it may act in
        self.topic_windows = dict(topic_windows or {})  # graph topic -> the ticks it carries
        self.topic_periods = dict(topic_periods or {})  # graph topic -> its own period
        for e in self.edges:
            if e.topic in self.topic_periods:
                own = self.topic_periods[e.topic]
                if not _is_int(own) or own <= 0 or own % self.periods[e.producer]:
                    raise ValueError(f"period of {e.topic} must be a whole multiple of its "
                                     f"producer {e.producer}'s")
        # (consumer, graph topic) -> the period at which the consumer takes that input, a
        # multiple of its own (a controller manager in the physics step takes its topics at
        # its updates only)
        self.input_periods = dict(input_periods or {})

    def active(self, node: str, tick: int) -> bool:
        """Whether ``tick`` is inside the node's window (always, for a node without one)."""
        window = self.windows.get(node)
        return window is None or (window[0] <= tick and (window[1] is None or tick < window[1]))

    def topic_window(self, producer: str, topic: str) -> Window | None:
        """The window of ``topic`` as ``producer`` publishes it: the topic's own, else the
        producer's, else None (every activation)."""
        return self.topic_windows.get(topic, self.windows.get(producer))

    def topic_period(self, producer: str, topic: str) -> int:
        """The ticks between samples of ``topic`` as ``producer`` publishes it: the topic's
        own period (``topic_periods``), else the producer's."""
        return self.topic_periods.get(topic) or self.periods[producer]

    def sample_ticks(self, producer: str, topic: str) -> tuple[int, int | None]:
        """The producer ticks of the first and last sample on ``topic`` (last None: to the
        run's end): its activations at its period (``topic_period``) inside the topic's
        window. First > last: none at all."""
        p = self.topic_period(producer, topic)
        window = self.topic_window(producer, topic)
        if window is None:
            return 0, None
        start, end = window
        return first_activation(p, start), None if end is None else (end - 1) // p * p

    def carries(self, producer: str, topic: str, tick: int) -> bool:
        """Whether the producer's activation at ``tick`` publishes ``topic``."""
        if tick % self.topic_period(producer, topic):
            return False
        window = self.topic_window(producer, topic)
        return window is None or (window[0] <= tick and (window[1] is None or tick < window[1]))

    def _topological_order(self) -> list[str]:
        """Nodes ordered so every same_tick producer precedes its consumers; ties by name."""
        indegree = {n: 0 for n in self.periods}
        succ: dict[str, set[str]] = {n: set() for n in self.periods}
        for e in self.edges:
            if e.mode == SAME_TICK and e.consumer not in succ[e.producer]:
                succ[e.producer].add(e.consumer)
                indegree[e.consumer] += 1
        ready = [n for n, d in indegree.items() if d == 0]
        heapq.heapify(ready)
        order = []
        while ready:
            n = heapq.heappop(ready)
            order.append(n)
            for m in succ[n]:
                indegree[m] -= 1
                if indegree[m] == 0:
                    heapq.heappush(ready, m)
        return order

    @property
    def n_ticks(self) -> int:
        """How many ticks the run has: 0 .. last_tick inclusive."""
        return self.last_tick + 1

    @cached_property
    def hyperperiod(self) -> int:
        """The schedule repeats with this many ticks: the lcm of all periods."""
        return math.lcm(*self.periods.values())

    def time_ns(self, tick: int) -> int:
        """The time of a tick in whole nanoseconds (``plan.timeutil.tick_time_ns``)."""
        return tick_time_ns(tick, self.tick_ns)

    def tick_at(self, ns: int) -> int:
        """The last tick whose time is at or before ``ns`` (a /clock value back to its tick)."""
        return tick_at_ns(ns, self.tick_ns)

    def is_due(self, node: str, tick: int) -> bool:
        """Whether the node acts at this tick."""
        return tick % self.periods[node] == 0 and (not self.windows or self.active(node, tick))

    @cached_property
    def _due_table(self) -> list[tuple[str, ...]]:
        return [
            tuple(n for n in self.order if k % self.periods[n] == 0)
            for k in range(self.hyperperiod)
        ]

    def due(self, tick: int) -> tuple[str, ...]:
        """The nodes acting at this tick, producers before same_tick consumers."""
        if self.hyperperiod <= 100_000:
            due = self._due_table[tick % self.hyperperiod]
        else:
            due = tuple(n for n in self.order if tick % self.periods[n] == 0)
        if self.windows:
            due = tuple(n for n in due if self.active(n, tick))
        return due

    def input_tick(self, edge: Edge, tick: int) -> int | None:
        """The producer tick whose sample the consumer uses at ``tick`` (None: no sample yet)."""
        p = self.topic_period(edge.producer, edge.topic)
        if edge.mode == SAME_TICK:
            wanted = (tick // p) * p
        elif tick == 0:
            return None
        else:
            wanted = ((tick - 1) // p) * p
        if self.windows or self.topic_windows:
            first, last = self.sample_ticks(edge.producer, edge.topic)
            if wanted < first or (last is not None and wanted > last):
                return None  # the topic carries nothing yet, or nothing any more
        return wanted

    def inputs_at(self, node: str, tick: int) -> list[tuple[int, int]]:
        """Which input samples ``node`` consumes at ``tick``: (index of the input in the
        node's declared inputs, producer tick of the sample), for every input that has a
        sample by then (a delayed input has none at tick 0) and that the node takes at this
        tick (``input_periods``: every n-th activation for some). The one answer every driver
        (in-process, node runtime, foreign feeder, master's messages) uses."""
        out = []
        for index, edge in enumerate(self.inputs_of[node]):
            if self.input_periods and tick % self.input_periods.get((node, edge.topic), 1):
                continue  # an input the node takes every n-th activation only
            wanted = self.input_tick(edge, tick)
            if wanted is not None:
                out.append((index, wanted))
        return out

    def first_activation(self, node: str, start: int) -> int:
        """The node's first activation at or after tick ``start`` (a window's first tick)."""
        return first_activation(self.periods[node], start)

    def wanted_samples(self, edge: Edge) -> tuple[int | None, int | None] | None:
        """The producer ticks of the first and last sample a windowed consumer can take on
        ``edge`` in its window (first None: its window is not opened yet, so only the newest
        sample so far may be wanted where it opens; last None: to the run's end), or None
        for a consumer without a window. First > last: it takes none."""
        window = self.windows.get(edge.consumer)
        if window is None:
            return None
        p, q = self.periods[edge.consumer], self.topic_period(edge.producer, edge.topic)
        back = 0 if edge.mode == SAME_TICK else 1  # a delayed input: strictly before

        def wanted(k: int) -> int:
            return (k - back) // q * q
        first = (None if window[0] >= NEVER
                 else wanted(self.first_activation(edge.consumer, window[0])))
        last = None if window[1] is None else wanted((window[1] - 1) // p * p)
        return first, last

    def activations(self, node: str, until: int | None = None) -> int:
        """How many times the node acts in ticks [0, ``until``) (default: the whole run),
        inside its window (``windows``) if it has one."""
        p = self.periods[node]
        last = self.last_tick if until is None else min(until - 1, self.last_tick)
        first, window = 0, self.windows.get(node)
        if window is not None:
            first = first_activation(p, window[0])
            last = last if window[1] is None else min(last, window[1] - 1)
        return (last // p * p - first) // p + 1 if last >= first else 0

    def samples(self, producer: str, topic: str, until: int | None = None) -> int:
        """How many samples ``producer`` publishes on ``topic`` in ticks [0, ``until``)
        (default: the whole run): its activations at the topic's period inside its window
        (what a bag of the run holds of a topic that is not latched)."""
        p = self.topic_period(producer, topic)
        first, last = self.sample_ticks(producer, topic)
        end = self.last_tick if until is None else min(until - 1, self.last_tick)
        last = end if last is None else min(last, end)
        return (last // p * p - first) // p + 1 if last >= first else 0

    def history_depth(self, edge: Edge) -> int:
        """History to keep on both sides of an edge: the samples a consumer may hold between
        its activations, twice, plus a fixed margin, plus the pipeline window (a producer
        may be that many ticks ahead of its consumer). The margin is also the window in which
        a reliable writer can still resend a sample that a starved reader missed (measured:
        7 samples were not enough on a loaded 2-core machine; a lost sample is a sequence-gap
        error, never a silent divergence)."""
        ratio = -(-self.periods[edge.consumer] // self.periods[edge.producer])
        return 2 * ratio + 64 + PIPELINE_WINDOW

    def output_depths(self, producer: str, topics) -> dict[str, int]:
        """The history to keep on each output topic of ``producer`` (``topics``): the
        deepest its consumers need (``history_depth``), 2 where nobody consumes it."""
        depth = {topic: 2 for topic in topics}
        for edge in self.edges:
            if edge.producer == producer:
                depth[edge.topic] = max(depth[edge.topic], self.history_depth(edge))
        return depth

    def driving_edge(self, node: str) -> Edge | None:
        """A same_tick input whose samples tell the node every tick it is due, or None.

        When the producer acts at every tick the consumer does (its period divides the
        consumer's), the arrival of the producer's sample of tick ``k`` is the news that
        tick ``k`` has begun. Such a node need not wake for /clock at all, which saves
        one wake-up per node per tick.
        """
        for edge in sorted(self.inputs_of[node], key=lambda e: e.topic):
            if (edge.mode == SAME_TICK
                    and self.periods[node] % self.topic_period(edge.producer, edge.topic) == 0):
                return edge
        return None

    def clock_driven(self) -> list[str]:
        """Nodes that need /clock to know when they are due."""
        return [n for n in self.order if self.driving_edge(n) is None]

    def leaves(self) -> list[str]:
        """Nodes whose outputs no node consumes (a camera): nothing waits for them."""
        producers = {e.producer for e in self.edges}
        return [n for n in self.order if n not in producers]
