"""The free-running runtime: one node on wall time, for live use beside ordinary ROS 2 tools.

Unlike lockstep, nothing waits for anyone: each input holds the latest message received
(from any publisher: a teleop terminal, a bag, another cosim node), and the node steps at
its rate. A node without same-tick inputs (physics) paces itself on the wall clock, scaled
by ``rtf``, and publishes ``/clock`` like Gazebo; the others follow ``/clock``. The step
classes are the same as in lockstep; only the results are no longer reproducible.

Live endpoints (``cosim-node ... --realtime --rosbridge/--live``) see what the node publishes
and receives (``observe``), put client messages on its inputs (``inbox``: each enters at the
node's next step) and, for a node that paces itself, pause and step it (``control``).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock

from nodes.contract import StepNode, Tick
from runtime.activation import Activation
from runtime.arrivals import Arrivals
from runtime.notes import Note
from runtime.protocol import CLOCK_TOPIC, decode_clock, encode_clock
from runtime.realtime_control import RealtimeControl
from runtime.transport.base import Transport

if TYPE_CHECKING:
    from plan.scenario import Scenario

POLL_NS = 50_000_000
PAUSED_POLL_NS = 10_000_000


class RealtimeRuntime:
    """Runs node ``name`` of a scenario on wall time until stopped."""

    def __init__(self, scenario: Scenario, name: str, node: StepNode, transport: Transport,
                 rtf: float = 1.0, publish_clock: bool | None = None):
        if rtf <= 0:
            raise ValueError(f"--rtf must be greater than zero, got {rtf}")
        self.plan = scenario.nodes[name]
        self.sched = scenario.schedule
        self.tick_ns = scenario.tick_ns
        self.period = self.plan.period_ticks
        self.node = node
        self.activation = Activation(self.plan, node, _print_note)
        self.transport = transport
        self.rtf = rtf
        if publish_clock is None:
            publish_clock = not any(i.mode == "same_tick" for i in self.plan.inputs)
        self.publish_clock = publish_clock
        self.latest: dict[str, object] = {}
        self.own_topic = {i.graph_topic: (i.topic, i.msg_type) for i in self.plan.inputs}
        latched = self.plan.latched_topics
        self.publishers = {t: transport.publisher(t, msg, 1 if t in latched else 10,
                                                  latched=t in latched)
                           for t, msg in self.plan.outputs.items()}
        for graph, (_, msg_type) in self.own_topic.items():
            transport.subscription(graph, msg_type, 10)
        self.clock_pub = transport.publisher(CLOCK_TOPIC, Clock, 10) if publish_clock else None
        if not publish_clock:
            transport.subscription(CLOCK_TOPIC, Clock, 10)
        self.stop_requested = False
        self.served = -1
        self.waiting_said = False  # the note on waiting for the first inputs was printed
        self.observe: Callable[[str, bytes], None] | None = None  # live endpoints' offer
        # client messages for the node's inputs (graph topics), taken at its next step
        self.inbox = Arrivals({g: m for g, (_, m) in self.own_topic.items()},
                              what="an input of this node")
        self.control = RealtimeControl(self.tick_ns) if publish_clock else None

    def request_stop(self, *_args) -> None:
        """Signal handler: leave the loop."""
        self.stop_requested = True

    def run(self) -> None:
        """Step at the node's rate until stopped."""
        if self.publish_clock:
            self._run_paced()
        else:
            self._run_following()

    def _run_paced(self) -> None:
        start = time.monotonic_ns()
        k = 0
        while not self.stop_requested:
            due_at = start + int(self.sched.time_ns(k) / self.rtf)
            while (left := due_at - time.monotonic_ns()) > 0 and not self.stop_requested:
                self._receive(min(left, POLL_NS))
            if self.control is not None and not self.control.may_tick(k):
                self._receive(PAUSED_POLL_NS)
                # no catching up
                start = time.monotonic_ns() - int(self.sched.time_ns(k) / self.rtf)
                continue
            clock = encode_clock(self.sched.time_ns(k))
            self.clock_pub.publish(clock)
            if self.observe is not None:
                self.observe(CLOCK_TOPIC, clock)
            if k % self.period == 0:
                self._step(k)
            k += 1

    def _run_following(self) -> None:
        while not self.stop_requested:
            now = self._receive(POLL_NS)
            if now is None:
                continue
            due = self.sched.tick_at(now)
            due -= due % self.period
            if due > self.served:
                self._step(due)

    def _receive(self, timeout_ns: int) -> int | None:
        """File every message; return the newest /clock time seen, if any."""
        newest = None
        for rec in self.transport.wait(timeout_ns):
            if rec.topic == CLOCK_TOPIC:
                newest = decode_clock(rec.data)
            elif rec.topic in self.own_topic:
                own, msg_type = self.own_topic[rec.topic]
                self.latest[own] = deserialize_message(rec.data, msg_type)
            if self.observe is not None:
                self.observe(rec.topic, rec.data)
        return newest

    def _step(self, k: int) -> None:
        tick = Tick(k, self.sched.time_ns(k))
        self.latest.update({self.own_topic[g][0]: msg for g, msg in self.inbox.take(k).items()})
        if missing := [i.graph_topic for i in self.plan.inputs
                       if i.mode == "same_tick" and i.topic not in self.latest]:
            if not self.waiting_said:  # once: a node that started first waits every time
                self.waiting_said = True
                print(f"note: {self.plan.name} at tick {k}: waiting for the first "
                      f"{', '.join(missing)} (it steps once every same_tick input has "
                      "arrived; until then it skips its activations)", file=sys.stderr,
                      flush=True)
            return
        items = self.activation(tick, dict(self.latest))
        for topic, data in items:
            self.publishers[topic].publish(data)
            if self.observe is not None:
                self.observe(topic, data)
        self.served = k


def _print_note(note: Note) -> None:
    print(f"note: {note.line()}", file=sys.stderr, flush=True)
