"""What the consumers of a gated foreign program see of its outputs.

A gated program (a Python one: cosim's gate runs in its process) may publish zero, one or
several messages per tick on each output: it publishes from callbacks and from timers, when
something changed or not at all. Its gate acknowledges every tick it was fed on
``/cosim/feed/<node>/taken`` (``std_msgs/Int64MultiArray``) as ``[tick, n_1, ..., n_m]``:
the tick, then how many messages the tick published on each output (``NodePlan.
gated_outputs`` order); before the first tick it sends ``[-1]`` ("ready"), and ``[-1, 1]``
once every output's publisher matches all its readers (the orchestrator then waits no
settle time). Consumers ignore both.

The rule (recorded in the manifest as ``FOREIGN_OUTPUT_RULE``): the sample of a gated
program's output at its tick ``r`` is the latest message it published at or before ``r``
(the last of tick ``r``'s messages, or the one held from an earlier tick); before its first
message there is none ("none yet"), and the consumer's step gets no entry for that input,
as for a delayed input at tick 0 (physics then applies zero velocity, as a real base does
before its first command). Every message, all of them in order, is in the bag and the
digest. Which tick a message belongs to is decided by the acknowledgement's counts, never
by arrival order or wall time, so the samples are the same in every run.
"""

from __future__ import annotations

from collections import deque

from std_msgs.msg import Int64MultiArray

from runtime.cdr.decode import decode
from runtime.exchange import InputHistory
from runtime.transport.base import Received

ACK_TYPE = Int64MultiArray
READY_TICK = -1
def decode_ack(data: bytes) -> tuple[int, list[int]]:
    """(tick, messages per output) of an acknowledgement (the tick is -1 for 'ready')."""
    values = list(decode(data, ACK_TYPE).data)
    return values[0], values[1:]


class SequenceError(RuntimeError):
    """A message or an acknowledgement was lost (a gap in its publisher's sequence)."""


class GatedChannel:
    """A consumer's input from a gated program's output: the program's messages and its
    gate's acknowledgements, arriving in any order, turned into one sample (or none yet) per
    activation of the program."""

    def __init__(self, topic: str, graph_topic: str, msg_type: type, producer_period: int,
                 index: int, drives: int | None = None):
        self.topic = topic
        self.graph_topic = graph_topic
        self.drives = drives
        self.period = producer_period
        self.index = index  # position of this output in the acknowledgement's counts
        self.history = InputHistory(graph_topic, msg_type)
        self.messages: deque[bytes] = deque()  # received, not yet given a tick
        self.counts: deque[tuple[int, int]] = deque()  # acknowledged (tick, count), pending
        self.latest: bytes | None = None  # the sample held: none yet until the first message
        self.received = 0
        self.next_ack = 0  # the producer tick the next acknowledgement must name

    def accept_ticks(self, rec: Received) -> list[int]:
        """File one message of the program; return the producer ticks now resolved."""
        if rec.sequence is not None and rec.sequence != self.received + 1:
            raise SequenceError(f"sequence gap on {self.graph_topic}: expected message "
                                f"{self.received + 1}, got {rec.sequence} (a message was lost)")
        self.received += 1
        self.messages.append(rec.data)
        return self._resolve()

    def acknowledged(self, tick: int, counts: list[int]) -> list[int]:
        """File an acknowledgement; return the producer ticks now resolved."""
        if tick == READY_TICK:
            return []
        if tick != self.next_ack:
            raise SequenceError(f"acknowledgements of {self.graph_topic}'s producer: expected "
                                f"tick {self.next_ack}, got {tick} (one was lost)")
        self.next_ack += self.period
        self.counts.append((tick, counts[self.index]))
        return self._resolve()

    def _resolve(self) -> list[int]:
        done = []
        while self.counts and len(self.messages) >= self.counts[0][1]:
            tick, count = self.counts.popleft()
            for _ in range(count):
                self.latest = self.messages.popleft()
            self.history.push_bytes(tick, self.latest)
            done.append(tick)
        return done

    def rebase(self, sent_before: int) -> None:
        """Foreign programs are never reset; nothing to start over."""
        raise SequenceError(f"{self.graph_topic} comes from a foreign program, which cannot "
                            "be reset")
