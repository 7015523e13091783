"""The orchestrator's stand-in for a foreign program: it feeds the program its inputs one
tick at a time and counts what the program publishes.

Feeding (a gated program, see ``orchestrator.proxies.foreign_launch``): the proxy subscribes to the
program's inputs on the run's topics and, for every tick the program is due at, once
``/clock`` has reached that tick and the schedule's samples are all here, publishes on the
program's private feed topics exactly the samples the schedule names (one per input, in
declaration order, the bytes as the producer sent them), then the tick's Clock. It feeds
the next due tick only after the program's gate acknowledged that it took this one, so
nothing of tick k+1 reaches the program before it has handled tick k.

Completion, for a gated program: its gate acknowledges each fed tick with how many messages
the tick published on each output (zero, one or several: from callbacks and timers alike),
and the activation is done once those messages are here; the digest covers exactly them,
in order. Where the scenario declares an exact count (``per_activation``,
``silent_at_start``) a different count is an error naming the topic, the tick and both
counts. An ungated program (no gate serves it: not Python and the RMW gate not built, see
``plan.gates``) is counted: an activation is done once every output carries its declared
number of messages (default 1); more is an error the moment it happens, fewer is caught by
the tick deadline, naming what is missing.
"""

from __future__ import annotations

import time

from rosgraph_msgs.msg import Clock

from orchestrator.lockstep.participants import Participant
from orchestrator.proxies.foreign_launch import ack_topic, clock_topic, feed_topic
from plan.errors import SimulationError
from plan.scenario import NodePlan
from plan.schedule import Schedule
from runtime.cdr.canonical import canonical_cdr
from runtime.exchange import output_digest
from runtime.gated_output import ACK_TYPE, READY_TICK, decode_ack
from runtime.lockstep import InputChannel, NodeFailure
from runtime.protocol import DONE, Done, Status, encode_clock
from runtime.recording import PartWriter
from runtime.transport.base import Received, Transport

SETTLE_S = 0.5


class ForeignProxy(Participant):
    """Feeds one foreign program and turns its outputs into status reports."""


    def __init__(self, plan: NodePlan, schedule: Schedule, transport: Transport,
                 recorder: PartWriter | None):
        self.name = plan.name
        self.plan = plan
        self.schedule = schedule
        self.period = plan.period_ticks
        self.per = {graph: plan.params.count(own) for own, graph in plan.output_names.items()}
        # messages per topic before activation n: per * n, less the silent tick 0
        self.skip = {graph: self.per[graph] - plan.params.count(own, 0)
                     for own, graph in plan.output_names.items()}
        self.classes = dict(plan.outputs)
        self.subs = {t: transport.subscription(t, cls, 1000) for t, cls in self.classes.items()}
        self.received: dict[str, list[bytes]] = {t: [] for t in self.classes}
        self.recorder = recorder
        self.activations = 0
        self.clock_tick = -1  # the latest tick the master published /clock for
        self.pending: list[Status] = []  # activations done without a message (silent)
        self._matched_since: float | None = None
        self.is_gated = plan.role.is_gated  # a gate (python or rmw) serves it: plan.gates
        self.own_of = {graph: own for own, graph in plan.output_names.items()}
        # gated: per output, how many of its messages the acknowledged activations hold
        self.ends: dict[str, list[int]] = {t: [] for t in self.classes}
        self.follows_clock = not self.is_gated  # a gated program sees only its fed clock
        self.channels: dict[str, InputChannel] = {}
        self.feeds = {}
        if self.is_gated:
            self._wire_feed(transport)

    def _wire_feed(self, transport: Transport) -> None:
        sched = self.schedule
        for inp, edge in zip(self.plan.inputs, sched.inputs_of[self.name], strict=True):
            depth = sched.history_depth(edge)
            self.channels[inp.graph_topic] = InputChannel(
                inp.topic, inp.graph_topic, inp.msg_type,
                sched.topic_period(inp.producer, inp.graph_topic))
            transport.subscription(inp.graph_topic, inp.msg_type, depth)
            self.feeds[inp.topic] = transport.publisher(feed_topic(self.name, inp.topic),
                                                        inp.msg_type, 10)
        self.clock_feed = transport.publisher(clock_topic(self.name), Clock, 10)
        self.ack = ack_topic(self.name)
        self.ack_sub = transport.subscription(self.ack, ACK_TYPE, 1000, latched=True)
        self.gate_ready = False
        # the gate saw every output's publisher match all its readers ([-1, 1]): no settle
        self.outputs_matched = False
        self.next_feed = 0  # the next due tick to feed
        self.awaiting: int | None = None  # a fed tick the gate has not acknowledged yet

    @property
    def topics(self) -> frozenset[str]:
        """The program's output topics, and for a gated one its inputs and acknowledgements."""
        if not self.is_gated:
            return frozenset(self.subs)
        return frozenset(self.subs) | frozenset(self.channels) | {self.ack}

    def ready(self) -> bool:
        """Whether the program has joined: its publishers matched for ``SETTLE_S``, and for
        a gated program every feed subscribed and the gate reported ready. Our readers
        seeing its writers does not prove its writers see our readers yet, and a volatile
        writer drops what it publishes before that: the settle time covers the other half
        of discovery, which cosim cannot observe in a program it does not run, unless the
        program's gate saw it (``[-1, 1]``: every output's publisher matched its readers)."""
        if self.is_gated and not (self.gate_ready and not self._unsubscribed()):
            return False
        if not all(sub.matched() >= 1 for sub in self.subs.values()):
            self._matched_since = None
            return False
        if self.is_gated and self.outputs_matched:  # the gate saw the other half
            return True
        now = time.monotonic()
        if self._matched_since is None:
            self._matched_since = now
        return now - self._matched_since >= SETTLE_S

    def _unsubscribed(self) -> list[str]:
        """Declared inputs the program has not subscribed to (on its feed)."""
        return [own for own, pub in self.feeds.items() if pub.matched() < 1]

    def not_ready_text(self) -> str:
        """What the program has not done yet, for the start-deadline message."""
        parts = []
        if self.is_gated:
            parts += [f"never subscribed to its declared input {own} (fed to it on "
                      f"{feed_topic(self.name, own)})" for own in self._unsubscribed()]
            if not parts and not self.gate_ready:
                parts.append(f"its cosim gate never reported ready on {self.ack} (is it an "
                             "rclpy program run by this interpreter, or, with the RMW gate, "
                             "a program on rcl that reads LD_PRELOAD? with use_sim_time "
                             "true?)")
        missing = [t for t, sub in self.subs.items() if sub.matched() < 1]
        if missing:
            parts.append("its outputs are not advertised yet: "
                         + ", ".join(f"{t} (0/1 publishers)" for t in missing))
        return f"is a foreign program that {'; '.join(parts) or 'has not settled'} (see its log)"

    def start_tick(self, tick: int) -> None:
        """/clock reached ``tick``: feed what is due; an activation that publishes nothing
        (``silent_at_start``) is done."""
        self.clock_tick = tick
        if self.is_gated:
            self._pump()
        self.pending += self._done_so_far()

    def drain(self) -> list[Status]:
        """Activations completed without a message."""
        done, self.pending = self.pending, []
        return done

    def take(self, rec: Received, current_tick: int) -> list[Status]:
        """File one message: an input to feed, an acknowledgement, or an output to count;
        return the DONE reports of activations now complete."""
        if rec.topic in self.channels:
            try:
                self.channels[rec.topic].accept(rec)
            except NodeFailure as exc:
                raise SimulationError(f"feeding foreign node {self.name}: {exc}",
                                      node=self.name, tick=current_tick) from None
            self._pump()
            return []
        if self.is_gated and rec.topic == self.ack:
            self._acknowledged(*decode_ack(rec.data), current_tick)
            return self._done_so_far()
        return self._count(rec, current_tick)

    def _acknowledged(self, tick: int, counts: list[int], current_tick: int) -> None:
        if tick == READY_TICK:
            self.gate_ready = True
            self.outputs_matched = self.outputs_matched or counts == [1]
            return
        if tick != self.awaiting:
            raise SimulationError(f"foreign node {self.name}: its gate acknowledged tick "
                                  f"{tick}, but tick {self.awaiting} was fed", node=self.name,
                                  tick=current_tick)
        activation = tick // self.period
        for topic, count in zip(self.plan.gated_outputs, counts, strict=True):
            own = self.own_of[topic]
            exact = self.plan.params.exact(own, activation)
            if exact is not None and count != exact:
                key = ("params.silent_at_start" if activation == 0
                       and self.plan.params.silent_at_start else f"params.per_activation.{own}")
                raise SimulationError(
                    f"foreign node {self.name} published {count} message(s) on {topic} at "
                    f"tick {tick}, and the scenario declares exactly {exact} ({key}). Leave "
                    f"{key} out to allow any number (its consumers see the latest sample).",
                    node=self.name, tick=tick)
            ends = self.ends[topic]
            ends.append((ends[-1] if ends else 0) + count)
        self.awaiting = None
        self._pump()

    def _pump(self) -> None:
        """Feed the next due tick when /clock has reached it, the previous one was taken
        and every sample the schedule names for it is here."""
        while (self.awaiting is None and self.gate_ready and self.next_feed <= self.clock_tick
               and self.next_feed <= self.schedule.last_tick):
            k = self.next_feed
            wanted = self.schedule.inputs_at(self.name, k)
            inputs = [self.plan.inputs[index] for index, _ in wanted]
            if not all(self.channels[inp.graph_topic].history.has(r)
                       for inp, (_, r) in zip(inputs, wanted, strict=True)):
                return
            for inp, (_, r) in zip(inputs, wanted, strict=True):
                self.feeds[inp.topic].publish(self.channels[inp.graph_topic].history.take_raw(r))
            self.clock_feed.publish(encode_clock(self.schedule.time_ns(k)))
            self.awaiting = k
            self.next_feed = k + self.period

    def _count(self, rec: Received, current_tick: int) -> list[Status]:
        messages = self.received[rec.topic]
        messages.append(canonical_cdr(rec.data, self.classes[rec.topic]))
        if self.is_gated:  # the gate's acknowledgement says which tick it belongs to
            return self._done_so_far()
        activation = (len(messages) - 1 + self.skip[rec.topic]) // self.per[rec.topic]
        if activation * self.period > current_tick:
            raise SimulationError(
                f"foreign node {self.name} published more than {self.per[rec.topic]} "
                f"message(s) on {rec.topic} at tick {current_tick}: message {len(messages)} "
                f"would belong to tick {activation * self.period}. Declare the count in "
                f"params.per_activation, or make the program publish once per input.",
                node=self.name, tick=current_tick)
        return self._done_so_far()

    def _done_so_far(self) -> list[Status]:
        """DONE reports of the activations up to /clock whose outputs are all in."""
        done = []
        while (self.activations * self.period <= self.clock_tick
               and self._complete(self.activations)):
            done.append(self._finish(self.activations))
            self.activations += 1
        return done

    def _span(self, topic: str, activation: int) -> tuple[int, int]:
        """Which of the messages received on ``topic`` belong to ``activation``."""
        if self.is_gated:
            ends = self.ends[topic]
            return (ends[activation - 1] if activation else 0), ends[activation]
        n, skip = self.per[topic], self.skip[topic]
        return max(activation * n - skip, 0), (activation + 1) * n - skip

    def _complete(self, activation: int) -> bool:
        if self.is_gated and activation >= len(self.ends[next(iter(self.ends))]):
            return False  # not acknowledged yet
        return all(len(self.received[t]) >= self._span(t, activation)[1] for t in self.per)

    def _finish(self, activation: int) -> Status:
        tick = activation * self.period
        items = []
        for topic in sorted(self.per):
            first, end = self._span(topic, activation)
            items += [(topic, data) for data in self.received[topic][first:end]]
        if self.recorder:
            self.recorder.write(tick, items)
        done = Done(self.name, tick, output_digest(tick, items).hex())
        return Status(self.name, DONE, tick, done=[done])

    def owed_text(self, tick: int) -> str:
        """What the program still owes for ``tick``, e.g. '0 of 1 messages on /cmd_vel'."""
        activation = tick // self.period
        if self.is_gated and activation >= len(self.ends[next(iter(self.ends))]):
            if self.awaiting is not None:
                return (f"tick {self.awaiting} was fed and its gate has not acknowledged it: "
                        "a callback or timer of that tick is still running, or blocked "
                        "(foreign program)")
            return (f"tick {self.next_feed} not fed yet (waiting for its inputs; "
                    "foreign program)")
        parts = []
        for t in sorted(self.per):
            first, end = self._span(t, activation)
            parts.append(f"{max(0, len(self.received[t]) - first)} of {end - first} "
                         f"message(s) on {t}")
        if self.is_gated:
            return ("its gate acknowledged the tick, but of the messages it counted only "
                    + ", ".join(parts) + " arrived (foreign program)")
        return ("it published " + ", ".join(parts) + " (a foreign program no gate serves "
                "(not Python, and the RMW gate is not built): it must publish exactly the "
                "declared count per tick, params.per_activation and params.silent_at_start; "
                "if it publishes fewer, declare that)")
