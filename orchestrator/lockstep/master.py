"""The lockstep master: one /clock per tick, advance when every due node reports done.

It only talks to the transport and asks the supervisor whether processes are alive;
spawning and shutdown live in ``orchestrator.lockstep.supervisor`` (after mosaik's split between
the scheduler and the simulator manager).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial

from diagnostic_msgs.msg import DiagnosticStatus
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from orchestrator.lockstep.acks import AckBook
from orchestrator.lockstep.loop_result import LoopResult, goal_reached
from orchestrator.lockstep.pace import pace_of
from orchestrator.lockstep.participants import Participant
from orchestrator.lockstep.supervisor import Supervisor
from orchestrator.ros_surface.simcontrol import PLAYING
from plan.errors import SimulationError
from plan.options import RunOptions
from plan.packing import ProcessLayout
from plan.roles import NodeRole
from plan.run_paths import RunPaths
from plan.scenario import Scenario
from plan.schedule import PIPELINE_WINDOW
from runtime.protocol import (
    CLOCK_TOPIC,
    COMMAND_TOPIC,
    DONE,
    ERROR,
    READY,
    RESETTING,
    STATUS_TOPIC,
    WINDOWED,
    Command,
    CommandMessage,
    Done,
    MetricBook,
    Status,
    decode_status,
    encode_clock,
    encode_command,
)
from runtime.recording import read_part
from runtime.transport.base import Transport

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

    def add(self, done: Done) -> None:
        """Account one activation reported done."""
        self.ticks += 1
        self.step_ns_total += done.step_ns
        self.step_ns_worst = max(self.step_ns_worst, done.step_ns)
        self.metrics.update(done.metrics)


class LockstepMaster:
    """Drives a scenario's ticks over a transport, watching the supervisor's processes."""

    def __init__(self, scenario: Scenario, transport: Transport, supervisor: Supervisor,
                 participants: dict[str, Participant], options: RunOptions,
                 layout: ProcessLayout, on_tick: Callable[[int], None] | None = None,
                 paths: RunPaths | None = None):
        self.scenario = scenario
        self.sched = scenario.schedule
        self.transport = transport
        self.supervisor = supervisor
        self.on_tick = on_tick
        self.paths = paths  # where nodes record: tells the tick a dead node was at
        self.clock_pub = transport.publisher(CLOCK_TOPIC, Clock, 1000)
        self.command_pub = transport.publisher(COMMAND_TOPIC, String, 10)
        self.epoch = 0
        self.windowings = 0  # OPEN and CLOSE handshakes so far (robots clients bring in)
        self.status_sub = transport.subscription(STATUS_TOPIC, DiagnosticStatus, 10_000)
        self.stats = {name: NodeStats() for name in scenario.nodes}
        self.last_status: dict[str, Status] = {}
        self.metric_book = MetricBook()  # reports carry the metrics that changed: all of them
        self.tick = -1
        self.participants = participants
        self.reader_of = {t: p for p in participants.values() for t in p.topics}
        roles = {name: plan.role for name, plan in scenario.nodes.items()}
        self.drainable = [p for n, p in participants.items() if roles[n].stood_in]
        # one /cosim/command subscription per cosim node process (the nodes packed into one
        # process share it; the orchestrator's own participants have none), and one /clock
        # subscription per such process that holds a node woken by /clock
        clock_driven = set(self.sched.clock_driven())
        self.command_subscribers = len(layout.node_processes)
        self.clock_subscribers = sum(1 for p in layout.node_processes
                                     if clock_driven.intersection(p.names))
        self.tick_limit_s = scenario.model.deadlines.tick / 1e9
        self.trailing = scenario.trailing_nodes
        # Without the pipeline option every node finishes each tick before the next (for
        # benchmarks); the outputs, digest and stop decision are the same either way.
        # A program that reads the run's /clock itself (an ungated foreign program) answers
        # tick by tick: no clock runs ahead for it. A gated one sees only its fed clock.
        strict = not options.pipeline
        self.may_trail = frozenset() if strict else self.trailing
        follows = any(p.follows_clock for p in participants.values())
        self.window = 1 if strict or follows else PIPELINE_WINDOW
        self.stop_on_goal = bool(scenario.model.success.stop_on_goal and scenario.model.has_goal)
        self.published, self.end = 0, None
        self.book: AckBook | None = None  # the running tick loop's (see _tick_of)
        self.pace = pace_of(options)  # --real-time-factor: ticks held back to the wall clock
        self.control = None  # the run's RunControl, while ``run`` goes
        self._next_liveness = 0.0
        self._next_sample = 0.0

    # -- start ---------------------------------------------------------------------------

    def wait_ready(self, started_at: float) -> None:
        """Wait until every node is ready and matched; name who is not at the deadline
        (counted from ``started_at``, when the nodes were started)."""
        deadline = started_at + self.scenario.model.deadlines.start / 1e9
        names = set(self.participants)
        ready: set[str] = set()
        while True:
            for status in self._statuses():
                if status.state == ERROR:
                    self._raise_node_error(status, "start")
            for name, participant in self.participants.items():
                if name not in ready and participant.ready():
                    self.stats[name].ready_s = time.monotonic() - started_at
                    ready.add(name)
            self._check_processes("start")
            if (ready == names and self.command_pub.matched() >= self.command_subscribers
                    and self.clock_pub.matched() >= self.clock_subscribers):
                return
            if time.monotonic() > deadline:
                raise SimulationError(self._start_timeout_text(names - ready))

    def _start_timeout_text(self, missing: set[str]) -> str:
        parts = []
        for name in sorted(missing):
            proc = self.supervisor.procs.get(name)
            if self.scenario.nodes[name].role is NodeRole.USER_STARTED:
                alive = "external process, started by you"
            else:
                alive = "process alive" if proc and proc.popen.poll() is None else "process gone"
            parts.append(f"node {name} ({alive}) {self.participants[name].not_ready_text()}")
        if not parts:
            parts.append(f"/clock has {self.clock_pub.matched()} of "
                         f"{self.clock_subscribers} subscriptions")
        limit = self.scenario.model.deadlines.start / 1e9
        return f"start deadline of {limit:g} s expired: " + "; ".join(parts) + "."

    # -- ticks -------------------------------------------------------------------------------

    def run(self, control=None) -> LoopResult:
        """Run every tick; stop early when the goal is reached (if the scenario says so).

        ``/clock`` may run up to ``window`` ticks ahead of the oldest tick a node still owes
        (a leaf such as a camera: its period more): a node acts on a tick as soon as the
        inputs the schedule names are there, so outputs cannot depend on how far ahead the
        clock is, and the stop decision is taken tick by tick in order, as in-process.
        ``control`` (a RunControl) may pause, step, stop or reset the run between ticks.
        """
        self.loop_started = time.monotonic()
        self.control = control
        book = self._new_book()
        n = self.sched.n_ticks
        requested = False  # a stop asked for through ``control``
        cleared = -1  # the last tick ``control`` let start (a paced tick may wait after it)
        while True:
            self._decide(book)
            k = self.published
            if self.end is None and k < n and book.may_start(k, self.window):
                if control and cleared != k:
                    playing = control.state == PLAYING
                    action = control.next_action(k, self._idle(k), partial(self._drain, book))
                    if action == "reset":
                        self._drain(book)
                        self._reset_nodes()
                        book = self._new_book()
                        control.reset_done()
                        cleared = -1
                        if self.pace is not None:
                            self.pace.restart()
                        continue
                    self._decide(book)  # ticks finished before a pause may have met the goal
                    if action == "stop" and self.end is None:
                        self.end, requested = k, True
                        book.close(k)
                    if self.end is not None:
                        continue
                    self._admit_robots(book, k)
                    cleared = k
                    if self.pace is not None and not (playing and control.state == PLAYING):
                        self.pace.restart()  # paused: a step goes at once, play from here
                if self.pace is not None:
                    wait = self.pace.wait_s(self.sched.time_ns(k))
                    if wait > 0:  # not yet: take reports meanwhile, no longer than that
                        self._take_reports(book, min(int(wait * 1e9), WAIT_SLICE_NS))
                        continue
                self._publish(book, k)
            elif self.end is not None or book.next_decided >= n:
                break
            else:
                self._take_reports(book)
        end = n if self.end is None else self.end
        book.close(end)
        self._drain(book)
        if control:
            control.finished(f"stopped by request before tick {end}" if requested
                             else f"the goal was reached at tick {end - 1}" if self.end
                             is not None else f"the run reached its duration ({n} ticks)")
        return LoopResult(book.hexdigest(), end, self.metrics(),
                          stopped_early=self.end is not None)

    def _new_book(self) -> AckBook:
        self.published, self.end = 0, None
        self.decided_metrics: dict[str, dict[str, float]] = {}
        self.book = AckBook(self.sched, self.may_trail)
        return self.book

    def _publish(self, book: AckBook, k: int) -> None:
        self.tick = k
        self.clock_pub.publish(encode_clock(self.sched.time_ns(k)))
        for participant in self.participants.values():
            participant.start_tick(k)
        book.expect(k, time.monotonic(), self.tick_limit_s)
        self.published = k + 1

    def _decide(self, book: AckBook) -> None:
        """Take the stop decision for every newly decided tick, in order; account folded ones."""
        while self.end is None and (item := book.take_decided()) is not None:
            tick, reports = item
            for name, done in reports.items():
                if done.metrics:
                    self.decided_metrics[name] = done.metrics
            if self.on_tick:
                self.on_tick(tick)
            if self.control:
                self.control.tick_decided(tick, reports)
            if self.stop_on_goal and goal_reached(self.decided_metrics, self.trailing):
                self.end = tick + 1
                book.close(self.end)
        for _, reports in book.take_folded():
            for name, done in reports.items():
                self.stats[name].add(done)

    def _drain(self, book: AckBook) -> None:
        """Take reports until nothing is owed (the ticks in flight are finished)."""
        while book.pending():
            self._take_reports(book)
            self._decide(book)
        self._decide(book)

    def _idle(self, k: int) -> Callable[[], None]:
        return lambda: self._check_processes(f"pause before tick {k}")

    def _reset_nodes(self) -> None:
        """Two-phase reset: every node stops and says what it sent; then all restart at 0."""
        self.epoch += 1
        sent = self._handshake(CommandMessage(Command.RESET, self.epoch), RESETTING)
        counts = {k[5:]: int(v) for values in sent.values() for k, v in values.items()
                  if k.startswith("sent:")}
        for name, participant in self.participants.items():
            if self.scenario.nodes[name].role is NodeRole.ORCHESTRATOR:
                counts.update(participant.sent)
                participant.reset()
        self._handshake(CommandMessage(Command.RESTART, self.epoch, counts), READY)
        self.stats = {name: NodeStats(ready_s=s.ready_s) for name, s in self.stats.items()}
        self.tick = -1

    def _admit_robots(self, book: AckBook, k: int) -> None:
        """Robots a client brings in or takes out (SpawnEntity, DeleteEntity of a planned
        robot, ``control.take_robot_requests``) at tick ``k``, where the external node and
        the world node both act: every tick before it finished, every node process told
        the robots' windows (an OPEN or CLOSE handshake, before any node can reach ``k``),
        then the request enters through the external node at ``k``, recorded."""
        take = getattr(self.control, "take_robot_requests", None)
        world = next((n for n, p in self.scenario.nodes.items() if p.windows), None)
        external = next((n for n, p in self.scenario.nodes.items()
                         if p.role is NodeRole.ORCHESTRATOR), None)
        if take is None or world is None or external is None or not (
                self.sched.is_due(world, k) and self.sched.is_due(external, k)):
            return
        requests = take()
        if not requests:
            return
        self._drain(book)
        for command in (Command.OPEN, Command.CLOSE):
            robots = {r.robot: k for r in requests if r.opens == (command is Command.OPEN)}
            if not robots:
                continue
            change = (self.scenario.open_robot if command is Command.OPEN
                      else self.scenario.close_robot)
            for robot in robots:
                change(robot, k)
            self.windowings += 1
            self._handshake(CommandMessage(command, self.windowings, robots), WINDOWED,
                            self.windowings)
        for request in requests:
            request.commit(k)

    def _handshake(self, command: CommandMessage, answer: str, epoch: int | None = None
                   ) -> dict[str, dict[str, str]]:
        """Publish a command and wait until every node answered it with ``answer`` (and
        ``epoch``, the reset epoch by default)."""
        epoch = self.epoch if epoch is None else epoch
        self.command_pub.publish(encode_command(command))
        pending = {n for n in self.participants
                   if self.scenario.nodes[n].role is not NodeRole.ORCHESTRATOR}
        replies: dict[str, dict[str, str]] = {}
        deadline = time.monotonic() + self.scenario.model.deadlines.start / 1e9
        while pending:
            for status in self._statuses():
                if status.state == answer and status.values.get("epoch") == str(epoch):
                    pending.discard(status.node)
                    replies[status.node] = status.values
                elif status.state == ERROR:
                    self._raise_node_error(status, "reset")
            self._check_processes("reset")
            if time.monotonic() > deadline:
                raise SimulationError(f"reset: node(s) {', '.join(sorted(pending))} did not "
                                      f"answer '{command.command.value}' in time")
        return replies

    def metrics(self) -> dict[str, dict[str, float]]:
        """The latest metrics each node reported."""
        return {name: dict(s.metrics) for name, s in self.stats.items()}

    def _take_reports(self, book: AckBook, wait_ns: int = WAIT_SLICE_NS) -> None:
        """Wait a little (at most ``wait_ns``) for reports and file them; fail on an error,
        a death or a deadline."""
        for status in self._statuses(wait_ns):
            if status.state == DONE:
                now = time.monotonic()
                for done in status.done:
                    book.record(done, now, self.tick_limit_s)
            elif status.state == ERROR:
                self._raise_node_error(status, f"tick {status.tick}")
        oldest = book.oldest_owed()
        self._check_processes(f"tick {min(oldest.values(), default=self.tick)}")
        if late := book.late(time.monotonic()):
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
            parts.append(f"node {name} did not finish tick {k} within the {limit:g} s tick "
                         f"deadline: {state}; {self.participants[name].owed_text(k)}")
        return "; ".join(parts) + ". Raise deadlines.tick in the scenario if it is just slow."

    # -- shared ------------------------------------------------------------------------------

    def _statuses(self, wait_ns: int = WAIT_SLICE_NS) -> list[Status]:
        out = []
        for rec in self.transport.wait(wait_ns):
            if rec.topic == STATUS_TOPIC:
                status = decode_status(rec.data)
                self.metric_book.complete(status)
                self.last_status[status.node] = status
                if status.node in self.participants:
                    self.participants[status.node].see(status)
                out.append(status)
            elif rec.topic in self.reader_of:
                out += self.reader_of[rec.topic].take(rec, self.tick)
        for participant in self.drainable:
            out += participant.drain()
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
            for name in proc.members:
                if name not in self.scenario.nodes:
                    continue
                self._drain_errors(name)
                tick = self._tick_of(name)
                when = when if tick is None else f"tick {tick}"
                shared = (f", in process {proc.name} with {', '.join(proc.members)}"
                          if len(proc.members) > 1 else "")
                raise SimulationError(
                    f"node {name} died at {when} ({proc.exit_text()}{shared}). "
                    f"Last lines of its log ({proc.log_path}):\n{proc.log_tail()}",
                    node=name, tick=max(self.tick, 0) if tick is None else tick)

    def _tick_of(self, name: str) -> int | None:
        """The tick a node was working on: the one after the last it recorded, or the
        oldest it owes (its latest reports may have died with it), None before the run."""
        if self.book is None:
            return None
        ticks = [self.book.oldest_owed().get(name, -1)]
        part = self.paths.part(name) if self.paths else None
        if part is not None and part.exists():
            last = max((tick for tick, _, _ in read_part(part)), default=None)
            if last is not None:
                ticks.append(last + self.sched.periods[name])
        return max(ticks) if max(ticks) >= 0 else None

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
