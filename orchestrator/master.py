"""The lockstep master: one /clock per tick, advance when every due node reports done.

It only talks to the transport and asks the supervisor whether processes are alive;
spawning and shutdown live in ``orchestrator.supervisor`` (after mosaik's split between
the scheduler and the simulator manager).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from nodes.protocol import (
    CLOCK_TOPIC,
    COMMAND_TOPIC,
    DONE,
    ERROR,
    READY,
    RESETTING,
    STATUS_TOPIC,
    Status,
    decode_status,
    encode_clock,
)
from nodes.transport import Transport
from orchestrator.acks import AckBook
from orchestrator.errors import SimulationError
from orchestrator.inprocess import RunResult, goal_reached
from orchestrator.scenario import Scenario
from orchestrator.supervisor import Supervisor

LIVENESS_PERIOD_S = 0.1
SAMPLE_PERIOD_S = 1.0
WAIT_SLICE_NS = 50_000_000


@dataclass
class NodeStats:
    """What the master learns about a node from its reports."""

    ticks: int = 0
    step_ns_total: int = 0
    step_ns_worst: int = 0
    ready_s: float | None = None
    metrics: dict[str, float] = field(default_factory=dict)

    def add(self, status: Status) -> None:
        """Account one 'done' report."""
        self.ticks += 1
        step = int(status.values.get("step_ns", "0"))
        self.step_ns_total += step
        self.step_ns_worst = max(self.step_ns_worst, step)
        for key, value in status.values.items():
            if key.startswith("metric."):
                self.metrics[key[7:]] = float(value)


class LockstepMaster:
    """Drives a scenario's ticks over a transport, watching the supervisor's processes."""

    def __init__(self, scenario: Scenario, transport: Transport, supervisor: Supervisor,
                 on_tick: Callable[[int], None] | None = None, proxies: dict | None = None):
        self.scenario = scenario
        self.sched = scenario.schedule
        self.transport = transport
        self.supervisor = supervisor
        self.on_tick = on_tick
        self.clock_pub = transport.publisher(CLOCK_TOPIC, Clock, 1000)
        self.command_pub = transport.publisher(COMMAND_TOPIC, String, 10)
        self.epoch = 0
        self.status_sub = transport.subscription(STATUS_TOPIC, DiagnosticStatus, 10_000)
        self.stats = {name: NodeStats() for name in scenario.nodes}
        self.last_status: dict[str, Status] = {}
        self.tick = -1
        self.proxies = proxies or {}
        self.proxy_of = {t: p for p in self.proxies.values() for t in p.topics}
        self.tick_limit_s = scenario.model.deadlines.tick / 1e9
        self.leaves = scenario.pipelined
        # COSIM_NO_PIPELINE=1 makes every node finish each tick before the next (benchmarks);
        # the outputs, digest and stop decision are the same either way.
        self.may_lag = frozenset() if os.environ.get("COSIM_NO_PIPELINE") else self.leaves
        self._next_liveness = 0.0
        self._next_sample = 0.0

    # -- start ---------------------------------------------------------------------------

    def wait_ready(self, started_at: float) -> None:
        """Wait until every node is ready and matched; name who is not at the deadline."""
        deadline = time.monotonic() + self.scenario.model.deadlines.start / 1e9
        names = set(self.scenario.nodes)
        ready: set[str] = set()
        while True:
            for proxy in self.proxies.values():
                if proxy.name not in ready and proxy.ready():
                    self.stats[proxy.name].ready_s = time.monotonic() - started_at
                    ready.add(proxy.name)
            for status in self._statuses():
                if status.state == READY and status.node in names:
                    if status.node not in ready:
                        self.stats[status.node].ready_s = time.monotonic() - started_at
                    ready.add(status.node)
                elif status.state == ERROR:
                    self._raise_node_error(status, "start")
            self._check_processes("start")
            cosim_nodes = len(names) - len(self.proxies)
            if (ready == names and self.command_pub.matched() >= cosim_nodes
                    and self.clock_pub.matched() >= len(self.sched.clock_driven())):
                return
            if time.monotonic() > deadline:
                raise SimulationError(self._start_timeout_text(names - ready))

    def _start_timeout_text(self, missing: set[str]) -> str:
        parts = []
        for name in sorted(missing):
            status = self.last_status.get(name)
            proc = self.supervisor.procs.get(name)
            if self.scenario.nodes[name].spec.external:
                alive = "external process, started by you"
            else:
                alive = "process alive" if proc and proc.popen.poll() is None else "process gone"
            what = (f"still waiting for discovery of {status.detail}" if status and status.detail
                    else "never reported on " + STATUS_TOPIC)
            if name in self.proxies:
                what = (f"is a foreign program whose outputs are not advertised yet: "
                        f"{self.proxies[name].unmatched()} (see its log)")
            parts.append(f"node {name} ({alive}) {what}")
        if not parts:
            parts.append(f"/clock has {self.clock_pub.matched()} of "
                         f"{len(self.sched.clock_driven())} subscriptions")
        limit = self.scenario.model.deadlines.start / 1e9
        return f"start deadline of {limit:g} s expired: " + "; ".join(parts) + "."

    # -- ticks -------------------------------------------------------------------------------

    def run(self, control=None) -> RunResult:
        """Run every tick; stop early when the goal is reached (if the scenario says so).

        A leaf node (nothing consumes its outputs, it reports no metrics: a camera) may
        still be working on tick ``k`` while the others run ``k + 1``: its acknowledgement
        is only needed before it is due again. ``control`` (a SimControl) may pause,
        single-step or reset the run between ticks.
        """
        self.loop_started = time.monotonic()
        stop_on_goal = self.scenario.model.success.stop_on_goal and self.scenario.model.goal
        book, k = AckBook(self.sched), 0
        while True:
            self._settle(book, k)
            if k and self.on_tick:
                self.on_tick(k - 1)
            if k and stop_on_goal and goal_reached(self.metrics(), self.leaves):
                self._settle(book, None)
                return RunResult(book.hexdigest(), k, self.metrics(), stopped_early=True)
            if k == self.sched.n_ticks:
                break
            if control and control.next_action(k, self._idle(k)) == "reset":
                self._settle(book, None)
                self._reset_nodes()
                book, k = AckBook(self.sched), 0
                continue
            self.tick = k
            self.clock_pub.publish(encode_clock(self.sched.time_ns(k)))
            book.expect(k, self.sched.due(k), time.monotonic() + self.tick_limit_s)
            k += 1
        self._settle(book, None)
        return RunResult(book.hexdigest(), self.sched.n_ticks, self.metrics())

    def _idle(self, k: int) -> Callable[[], None]:
        return lambda: self._check_processes(f"pause before tick {k}")

    def _reset_nodes(self) -> None:
        """Two-phase reset: every node stops and says what it sent; then all restart at 0."""
        self.epoch += 1
        sent = self._handshake(f"reset {self.epoch}", RESETTING)
        counts = {k[5:]: int(v) for values in sent.values() for k, v in values.items()
                  if k.startswith("sent:")}
        self._handshake(f"restart {self.epoch} {json.dumps(counts)}", READY)
        self.stats = {name: NodeStats(ready_s=s.ready_s) for name, s in self.stats.items()}
        self.tick = -1

    def _handshake(self, command: str, answer: str) -> dict[str, dict[str, str]]:
        """Publish a command and wait until every node answered it with ``answer``."""
        self.command_pub.publish(serialize_message(String(data=command)))
        pending, replies = set(self.scenario.nodes), {}
        deadline = time.monotonic() + self.scenario.model.deadlines.start / 1e9
        while pending:
            for status in self._statuses():
                if status.state == answer and status.values.get("epoch") == str(self.epoch):
                    pending.discard(status.node)
                    replies[status.node] = status.values
                elif status.state == ERROR:
                    self._raise_node_error(status, "reset")
            self._check_processes("reset")
            if time.monotonic() > deadline:
                raise SimulationError(f"reset: node(s) {', '.join(sorted(pending))} did not "
                                      f"answer '{command.split()[0]}' in time")
        return replies

    def metrics(self) -> dict[str, dict[str, float]]:
        """The latest metrics each node reported."""
        return {name: dict(s.metrics) for name, s in self.stats.items()}

    def _settle(self, book: AckBook, before_tick: int | None) -> None:
        """Take reports until nothing owed blocks ``before_tick`` (None: until nothing is owed)."""
        while blocking := book.blocking(before_tick, self.may_lag):
            for status in self._statuses():
                if status.state == DONE and book.record(status.tick, status.node, status.digest):
                    self.stats[status.node].add(status)
                elif status.state == ERROR:
                    self._raise_node_error(status, f"tick {status.tick}")
            oldest = min(t for t, _ in blocking)
            self._check_processes(f"tick {oldest}")
            late = [(t, n) for t, n in blocking if book.owed.get((t, n), 1e300) < time.monotonic()]
            if late:
                tick = min(t for t, _ in late)
                names = {n for t, n in late if t == tick}
                raise SimulationError(self._late_text(tick, names), node=min(names), tick=tick)

    def _late_text(self, k: int, pending: set[str]) -> str:
        limit = self.scenario.model.deadlines.tick / 1e9
        parts = []
        for name in sorted(pending):
            proc = self.supervisor.procs.get(name)
            if proc is None:
                state = "external process, not supervised"
            elif proc.popen.poll() is None:
                state = f"process alive (pid {proc.popen.pid}, {_proc_state(proc)})"
            else:
                state = f"process gone ({proc.exit_text()})"
            plan = self.scenario.nodes[name]
            needs = [f"{i.graph_topic} of tick {self.sched.input_tick(e, k)}"
                     for e, i in zip(self.sched.inputs_of[name], plan.inputs, strict=True)
                     if self.sched.input_tick(e, k) is not None]
            waiting = f"; it needs {', '.join(needs)}" if needs else "; it needs no input"
            if name in self.proxies:
                waiting = f"; {self.proxies[name].missing(k)} (foreign program)"
            parts.append(f"node {name} did not finish tick {k} within the {limit:g} s tick "
                         f"deadline: {state}{waiting}")
        return "; ".join(parts) + ". Raise deadlines.tick in the scenario if it is just slow."

    # -- shared ------------------------------------------------------------------------------

    def _statuses(self) -> list[Status]:
        out = []
        for rec in self.transport.wait(WAIT_SLICE_NS):
            if rec.topic == STATUS_TOPIC:
                status = decode_status(rec.data)
                self.last_status[status.node] = status
                out.append(status)
            elif rec.topic in self.proxy_of:
                out += self.proxy_of[rec.topic].accept(rec, self.tick)
        return out

    def _check_processes(self, when: str) -> None:
        now = time.monotonic()
        if now < self._next_liveness:
            return
        self._next_liveness = now + LIVENESS_PERIOD_S
        if now >= self._next_sample:
            self._next_sample = now + SAMPLE_PERIOD_S
            self.supervisor.sample()
        for proc in self.supervisor.dead():
            if proc.name in self.scenario.nodes:
                self._drain_errors(proc.name)
                raise SimulationError(
                    f"node {proc.name} died at {when} ({proc.exit_text()}). "
                    f"Last lines of its log ({proc.log_path}):\n{proc.log_tail()}",
                    node=proc.name, tick=max(self.tick, 0))

    def _drain_errors(self, name: str) -> None:
        """A node that reported an error before dying: report that error instead."""
        for status in self._statuses():
            if status.state == ERROR:
                self._raise_node_error(status, f"tick {status.tick}")
        last = self.last_status.get(name)
        if last and last.state == ERROR:
            self._raise_node_error(last, f"tick {last.tick}")

    def _raise_node_error(self, status: Status, when: str) -> None:
        where = f"tick {status.tick}" if status.tick >= 0 else when
        raise SimulationError(f"node {status.node} failed at {where}: {status.detail.rstrip()}",
                              node=status.node, tick=status.tick)


def _proc_state(proc) -> str:
    try:
        return f"state {proc.ps.status()}"
    except Exception:  # noqa: BLE001 - best effort description
        return "state unknown"
