"""The lockstep node runtime: wraps one step node for a transport.

At each tick the orchestrator publishes on /clock, this runtime waits for exactly the
input samples the schedule names, calls ``step``, publishes the outputs stamped with the
tick's time, records them, and reports ``done`` with the digest of what it published.
Only this module (and the transports) touch the network.
"""

from __future__ import annotations

import os
import signal
import sys
import time
import traceback
from collections import deque
from typing import TYPE_CHECKING

from diagnostic_msgs.msg import DiagnosticStatus
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from nodes.contract import StepNode, Tick
from nodes.live_params import ParamsInput
from plan.gates import ack_topic
from runtime.activation import Activation
from runtime.disk import WriteFailed
from runtime.exchange import SHARED_DECODER, InputHistory, output_digest
from runtime.gated_output import ACK_TYPE, GatedChannel, SequenceError, decode_ack
from runtime.intruders import explain_gap
from runtime.notes import Note, NoteWriter
from runtime.protocol import (
    CLOCK_TOPIC,
    COMMAND_TOPIC,
    ERROR,
    READY,
    RESETTING,
    STATUS_TOPIC,
    WAITING,
    WINDOWED,
    Command,
    CommandMessage,
    Done,
    MetricChanges,
    Status,
    decode_clock,
    decode_command,
    done_status,
    encode_status,
)
from runtime.recording import PartWriter
from runtime.timing import TimeSplit
from runtime.transport.base import Received, Transport

if TYPE_CHECKING:
    from plan.packing import ProcessLayout
    from plan.scenario import Scenario

POLL_NS = 100_000_000  # how often a waiting node checks for signals and its parent
MAX_BATCH = 64  # activations per 'done' report, at most
REPORT_LATEST_S = 0.05  # a step running this long first reports the activations before it
STATUS_PERIOD_S = 0.05  # how often a starting node checks its discovery
HEARTBEAT_S = 1.0  # a starting node repeats an unchanged report this often: one sent before
# the orchestrator's reader matched its publisher may be lost, and only changes are sent


class NodeFailure(RuntimeError):
    """The runtime cannot go on (sequence gap, step error); the message says why."""


class InputChannel:
    """One subscribed input: tick bookkeeping by sequence number, and its sample history."""

    def __init__(self, topic: str, graph_topic: str, msg_type: type, producer_period: int,
                 drives: int | None = None, first: int = 0):
        self.topic = topic
        self.first = first  # the producer tick of its first sample (a robot's topic: at entry)
        self.drives = drives  # consumer period, when this input announces the consumer's ticks
        self.graph_topic = graph_topic
        self.history = InputHistory(graph_topic, msg_type)
        self.period = producer_period
        self.received = 0
        self.base = 0  # the producer's messages sent before the last reset

    def accept(self, rec: Received) -> int:
        """Store a sample; return its producer tick (n-th message = n-th activation in the
        topic's window, ``Schedule.sample_ticks``)."""
        if rec.sequence is not None:
            if rec.sequence <= self.base:
                return -1  # sent before a reset, still in flight: not part of this run
            if rec.sequence != self.base + self.received + 1:
                raise NodeFailure(f"sequence gap on {self.graph_topic}: expected message "
                                  f"{self.base + self.received + 1}, got {rec.sequence} "
                                  "(a message was lost)")
        tick = self.first + self.received * self.period
        self.history.push_bytes(tick, rec.data)
        self.received += 1
        return tick

    def accept_ticks(self, rec: Received) -> list[int]:
        """``accept``, as the list of producer ticks resolved (a GatedChannel's interface)."""
        tick = self.accept(rec)
        return [tick] if tick >= 0 else []

    def rebase(self, sent_before: int) -> None:
        """Start over after a reset: the producer had sent ``sent_before`` messages."""
        self.base = sent_before
        self.received = 0
        self.history.samples.clear()


class LockstepRuntime:
    """Runs one node of a scenario in lockstep with the orchestrator (its step ``node`` may
    be attached after construction, before ``run``)."""

    def __init__(self, scenario: Scenario, name: str, node: StepNode | None, transport: Transport,
                 recorder: PartWriter | None = None, notes: NoteWriter | None = None,
                 *, layout: ProcessLayout):
        self.scenario = scenario
        self.layout = layout  # the run's processes: consumers packed together share a reader
        self.name = name
        self.plan = scenario.nodes[name]
        self.sched = scenario.schedule
        self.activation: Activation | None = None
        self.node = node  # builds the activation (a packed process attaches it later)
        self.transport = transport
        self.recorder = recorder
        self.notes = notes
        self.stop_requested = False
        self.in_step = False
        self._next_upstream_check = 0.0
        self.parent_pid = int(os.environ.get("COSIM_PARENT_PID", "0")) or None
        self.step_delay_s = (self.plan.spec.debug.step_delay or 0) / 1e9
        self.clocks: deque[int] = deque()  # ticks announced, by /clock or by a driving input
        self.unreported: list[Done] = []  # activations served since the last 'done' report
        self.metric_changes = MetricChanges()
        self.alarm = False  # SIGALRM reports them during a slow step (install_stop_handlers)
        self.timing = TimeSplit()  # wall time per part of the loop, for the manifest
        self.batch = None  # a packed process's DoneBatch: its nodes' reports in one message
        self._start_report: tuple[str, str] | None = None  # (state, unmatched) last sent
        self._next_start_check = 0.0
        self._next_heartbeat = 0.0
        self._wire()

    @property
    def node(self) -> StepNode | None:
        """The node's step class (None until attached)."""
        return self.activation.node if self.activation else None

    @node.setter
    def node(self, node: StepNode | None) -> None:
        self.activation = (Activation(self.plan, node, self.write_note, ParamsInput.of(self.plan))
                           if node is not None else None)
        self._share_inputs()

    def _share_inputs(self) -> None:
        """A node that only reads its inputs decodes each sample in the process's shared
        decoder: the nodes packed with it that read the same sample get the same message."""
        node = self.activation.node if self.activation is not None else None
        shared = SHARED_DECODER if node is not None and node.shares_inputs else None
        for channel in getattr(self, "inputs", {}).values():
            channel.history.shared = shared

    def _wire(self) -> None:
        sched, plan = self.sched, self.plan
        depth = sched.output_depths(self.name, plan.outputs)
        self.expected_subscribers = self.layout.subscribers(self.name)
        latched = plan.latched_topics
        self.publishers = {t: self.transport.publisher(t, msg, 1 if t in latched else depth[t],
                                                       latched=t in latched)
                           for t, msg in plan.outputs.items()}
        self.inputs: dict[str, InputChannel | GatedChannel] = {}
        self.input_subs = {}
        self.acks: dict[str, list[GatedChannel]] = {}  # a gated producer's ack topic -> inputs
        driver = sched.driving_edge(self.name)
        for edge, inp in zip(sched.inputs_of[self.name], plan.inputs, strict=True):
            period = sched.topic_period(inp.producer, inp.graph_topic)  # its samples
            drives = sched.periods[self.name] if edge == driver else None
            depth = sched.history_depth(edge)
            producer = self.scenario.nodes[inp.producer]
            if producer.role.is_gated:  # any number of messages per tick: its gate says how many
                channel = GatedChannel(inp.topic, inp.graph_topic, inp.msg_type, period,
                                       producer.gated_outputs.index(inp.graph_topic), drives)
                acks = ack_topic(inp.producer)
                if acks not in self.acks:
                    self.acks[acks] = []
                    self.input_subs[acks] = self.transport.subscription(
                        acks, ACK_TYPE, depth, latched=True)
                self.acks[acks].append(channel)
                depth = max(depth, 1000)  # a burst of messages in one tick is not lost
            else:
                channel = InputChannel(inp.topic, inp.graph_topic, inp.msg_type, period, drives,
                                       sched.sample_ticks(inp.producer, inp.graph_topic)[0])
            channel.history.keep_for(sched, edge)  # a dormant node keeps no samples
            self.inputs[inp.graph_topic] = channel
            self.input_subs[inp.graph_topic] = self.transport.subscription(
                inp.graph_topic, inp.msg_type, depth)
        # A node told of its ticks by a same_tick input does not wake for /clock.
        self.clock_sub = (self.transport.subscription(CLOCK_TOPIC, Clock, 1000)
                          if driver is None else None)
        self.command_sub = self.transport.subscription(COMMAND_TOPIC, String, 10)
        self.sent = {t: 0 for t in self.publishers}
        self.status_pub = self.transport.publisher(STATUS_TOPIC, DiagnosticStatus, 1000)
        self._share_inputs()

    # -- start ---------------------------------------------------------------------------

    def unmatched(self) -> list[str]:
        """Topics whose discovery is not complete, e.g. '/scan (0/1 subscriptions)'."""
        out = []
        for topic, pub in self.publishers.items():
            if (n := pub.matched()) < self.expected_subscribers[topic]:
                out.append(f"{topic} ({n}/{self.expected_subscribers[topic]} subscriptions)")
        subs = [*self.input_subs.items(), (COMMAND_TOPIC, self.command_sub)]
        if self.clock_sub is not None:
            subs.append((CLOCK_TOPIC, self.clock_sub))
        for topic, sub in subs:
            if sub.matched() < 1:
                out.append(f"{topic} (0/1 publishers)")
        if self.status_pub.matched() < 1:
            out.append(f"{STATUS_TOPIC} (0/1 subscriptions)")
        return out

    def wait_for_start(self) -> None:
        """Report waiting/ready until the first /clock arrives."""
        while not self.clocks and not self.stop_requested:
            self.report_start(time.monotonic())
            self.receive(int(STATUS_PERIOD_S * 1e9))
            self.check_parent()  # a parent-death signal missed at start must not keep it

    # -- run -------------------------------------------------------------------------------

    def receive(self, timeout_ns: int) -> None:
        """Take everything the transport has within the timeout and file it."""
        waited = time.perf_counter_ns()
        received = self.transport.wait(timeout_ns)
        self.timing.add("wait", waited)
        for rec in received:
            if rec.topic == CLOCK_TOPIC:
                self.clocks.append(self.sched.tick_at(decode_clock(rec.data)))
                continue
            if rec.topic == COMMAND_TOPIC:
                self.on_command(decode_command(rec.data))
                continue
            try:
                if rec.topic in self.acks:
                    tick, counts = decode_ack(rec.data)
                    resolved = [(c, c.acknowledged(tick, counts)) for c in self.acks[rec.topic]]
                else:
                    channel = self.inputs[rec.topic]
                    resolved = [(channel, channel.accept_ticks(rec))]
            except (SequenceError, NodeFailure) as exc:
                raise NodeFailure(explain_gap(self.transport, rec.topic, str(exc))) from None
            for channel, ticks in resolved:
                if channel.drives:
                    self.clocks.extend(t for t in ticks if t % channel.drives == 0)

    def run(self) -> None:
        """Serve ticks until stopped (SIGINT/SIGTERM) or the parent goes away."""
        self.wait_for_start()
        self.timing.start()
        try:
            self._serve()
        finally:
            self.timing.stop()

    def _serve(self) -> None:
        """The run loop: serve the announced ticks, report, wait for more."""
        while not self.stop_requested:
            self.serve_announced()
            if self.stop_requested:
                break
            self.receive(POLL_NS)
            self.check_parent()
            if self.finished():
                return  # the run is over (or the orchestrator died): nothing will come

    def serve_announced(self) -> None:
        """Serve every announced tick whose inputs are here, then report them."""
        while self.clocks and self.try_tick(self.clocks[0]):
            self.clocks.popleft()
        self.report_done()

    def check_parent(self) -> None:
        """Stop when the orchestrator that started this process is gone."""
        if self.parent_pid and os.getppid() != self.parent_pid:
            raise NodeFailure("the orchestrator went away; stopping")

    def finished(self) -> bool:
        """Nothing is announced and every publisher this node listens to has gone."""
        return not self.clocks and self.upstream_gone()

    def report_start(self, now: float, period: float = STATUS_PERIOD_S) -> None:
        """Before the first tick: check discovery every ``period`` and report waiting
        (naming what is unmatched) or ready when that changed, or HEARTBEAT_S after the
        last report. Once ready it checks no more: the orchestrator counts a node ready
        from its first 'ready' report."""
        if now < self._next_start_check:
            return
        self._next_start_check = now + period
        report = self._start_report
        if report is None or report[0] != READY:
            missing = self.unmatched()
            report = (WAITING if missing else READY, "; ".join(missing))
        if report != self._start_report or now >= self._next_heartbeat:
            self.report(Status(self.name, report[0], detail=report[1]))
            self._start_report = report
            self._next_heartbeat = now + HEARTBEAT_S

    def on_command(self, message: CommandMessage) -> None:
        """Handle the orchestrator's reset handshake (see runtime.protocol)."""
        epoch = str(message.epoch)
        if message.command is Command.RESET:
            self.report_done()
            values = {"epoch": epoch, **{f"sent:{t}": str(n) for t, n in self.sent.items()}}
            self.report(Status(self.name, RESETTING, values=values))
        elif message.command in (Command.OPEN, Command.CLOSE):
            change = (self.scenario.open_robot if message.command is Command.OPEN
                      else self.scenario.close_robot)
            for robot, tick in message.sent.items():
                change(robot, tick)
            self.rewindow()
            self.report(Status(self.name, WINDOWED, values={"epoch": epoch}))
        elif message.command is Command.RESTART:
            for topic, channel in self.inputs.items():
                channel.rebase(message.sent.get(topic, 0))
            self.clocks.clear()
            self.metric_changes.restart()
            self.activation.restart(self.scenario.model.seed)
            if self.recorder:
                self.recorder.truncate()
            if self.notes:
                self.notes.truncate()
            self.report(Status(self.name, READY, values={"epoch": epoch}))

    def rewindow(self) -> None:
        """After a robot's window opened: each input on its topics counts its samples from
        the producer's first activation in the window (none has come before)."""
        for inp in self.plan.inputs:
            channel = self.inputs[inp.graph_topic]
            if isinstance(channel, InputChannel) and not channel.received:
                channel.first = self.sched.sample_ticks(inp.producer, inp.graph_topic)[0]

    def upstream_gone(self) -> bool:
        """Whether every publisher this node listens to has disappeared (checked twice a second)."""
        now = time.monotonic()
        if now < self._next_upstream_check:
            return False
        self._next_upstream_check = now + 0.5
        subs = list(self.input_subs.values())
        if self.clock_sub is not None:
            subs.append(self.clock_sub)
        return bool(subs) and all(sub.matched() == 0 for sub in subs)

    def try_tick(self, k: int) -> bool:
        """Act at tick ``k`` if due and its inputs are all here; True when the tick is served."""
        if not self.sched.is_due(self.name, k):
            return True
        wanted = {}
        for index, r in self.sched.inputs_at(self.name, k):
            inp = self.plan.inputs[index]
            if not self.inputs[inp.graph_topic].history.has(r):
                return False
            wanted[inp.topic] = (inp.graph_topic, r)
        taken = time.perf_counter_ns()
        inputs = {own: self.inputs[g].history.take(r) for own, (g, r) in wanted.items()}
        # a gated foreign producer's output before its first message: none yet, no entry
        inputs = {own: msg for own, msg in inputs.items() if msg is not None}
        self.timing.add("deserialise", taken)
        self.activate(Tick(k, self.sched.time_ns(k)), inputs)
        return True

    def activate(self, tick: Tick, inputs: dict) -> None:
        """Step, publish, record and report one activation."""
        if self.step_delay_s:
            time.sleep(self.step_delay_s)  # test-only slowdown; must not change any output
        armed = self.alarm and bool(self.unreported)
        if armed:  # a slow or hung step must not hide the ticks served before it
            signal.setitimer(signal.ITIMER_REAL, REPORT_LATEST_S)
        start = time.perf_counter_ns()
        self.in_step = True
        try:
            items = self.activation(tick, inputs)
        except Exception as exc:
            self.report_error(tick.index, exc)
            raise NodeFailure(f"step failed at tick {tick.index}") from exc
        finally:
            self.in_step = False
            if armed:
                signal.setitimer(signal.ITIMER_REAL, 0)
        stepped = self.timing.span("step", start, self.activation.stepped_ns)
        now = self.timing.add("serialise", stepped)
        step_ns = now - start
        for topic, data in items:
            self.publishers[topic].publish(data)
            self.sent[topic] += 1
        now = self.timing.add("publish", now)
        if self.recorder:
            try:
                self.recorder.write(tick.index, items)
            except WriteFailed as exc:  # a full disk: the run stops at this tick, named
                self.report_error(tick.index, exc)
                raise NodeFailure(f"stopped at tick {tick.index}: {exc}") from exc
            now = self.timing.add("record", now)
        digest = output_digest(tick.index, items).hex()
        self.timing.add("digest", now)
        metrics, full = self.metric_changes.report(
            {k: float(v) for k, v in self.node.metrics().items()})
        self.unreported.append(Done(self.name, tick.index, digest, step_ns, metrics, full))
        if len(self.unreported) >= MAX_BATCH:
            self.report_done()

    def write_note(self, note: Note) -> None:
        """Write what the node noted to its log and its notes file."""
        print(f"note: {note.line()}", file=sys.stderr, flush=True)
        if self.notes:
            self.notes.write(note)

    def report_done(self, *_signal) -> None:
        """Report the activations served since the last report, in one message. Also the
        SIGALRM handler of a slow step."""
        batch, self.unreported = self.unreported, []
        if batch and self.batch is not None:
            self.batch.add(batch)
        elif batch:
            self.report(done_status(self.name, batch))

    def report(self, status: Status) -> None:
        """Publish a status message (after the process's batched done reports: the
        orchestrator reads each node's reports in the order they were made)."""
        if self.batch is not None:
            self.batch.flush()
        start = time.perf_counter_ns()
        self.status_pub.publish(encode_status(status))
        self.timing.add("report", start)

    def report_error(self, tick: int, exc: BaseException) -> None:
        """Report an exception with a traceback excerpt, and make sure it is delivered
        (after the activations served before it)."""
        self.report_done()
        excerpt = "".join(traceback.format_exception(exc)[-6:])
        detail = f"{type(exc).__name__}: {exc}\n{excerpt}"
        self.report(Status(self.name, ERROR, tick, detail=detail))
        flush = getattr(self.status_pub, "flush", None)
        if flush:
            flush(2.0)

    def request_stop(self, *_args) -> None:
        """Signal handler: leave the loop after the current wait; interrupt a step in progress
        (a step that never returns must not hold shutdown up until SIGKILL)."""
        self.stop_requested = True
        if self.in_step:
            raise KeyboardInterrupt


def install_stop_handlers(runtime: LockstepRuntime) -> None:
    """SIGINT and SIGTERM end the run loop cleanly (exit code 0, no traceback); SIGALRM
    reports the activations served before a step that runs long."""
    signal.signal(signal.SIGINT, runtime.request_stop)
    signal.signal(signal.SIGTERM, runtime.request_stop)
    signal.signal(signal.SIGALRM, runtime.report_done)
    runtime.alarm = True
