"""What every driver of a step node shares: stamping, serialising and hashing outputs.

Both the multi-process runtime and the in-process reference go through these functions,
so the bytes (and hence the digest) cannot differ between them.
"""

from __future__ import annotations

import hashlib
import struct
from collections import deque
from collections.abc import Iterable
from typing import Any

from builtin_interfaces.msg import Time
from tf2_msgs.msg import TFMessage

from nodes.contract import Tick, take_output_marks
from plan.timeutil import NS_PER_S
from runtime.cdr.decode import decode
from runtime.cdr.encode import ConstantTails, encode, header_first, stamped


class StepContractError(RuntimeError):
    """A step returned something other than one message of the declared type per output."""


def stamp(tick: Tick) -> Time:
    """The builtin_interfaces/Time of a tick."""
    return Time(sec=tick.time_ns // NS_PER_S, nanosec=tick.time_ns % NS_PER_S)


def prepare_outputs(node: str, declared: dict[str, type], names: dict[str, str], tick: Tick,
                    outputs: dict[str, Any], latched: frozenset[str] = frozenset(),
                    first: bool = False, tails: ConstantTails | None = None,
                    unconsumed: frozenset[str] = frozenset()) -> list[tuple[str, bytes]]:
    """Check, stamp and serialise a step's outputs: [(graph topic, CDR bytes)] sorted by topic.

    ``declared`` maps the node's own topic names to message classes and ``names`` maps them
    to graph topics (after remap). ``latched`` outputs (own names) are due at the node's
    ``first`` activation only, the others at every one. A message with a ``header`` gets
    the tick's stamp; so does every transform of a ``tf2_msgs/TFMessage``. A message its
    step marked constant (``nodes.contract.constant_message``) is serialised once into the
    node's ``tails`` while the step gives the same object (encoded every time without
    ``tails``); one it handed with its bytes (``encoded_message``) gets the stamp written in
    front of them. A message marked quiet (``quiet_message``) on an output no node of the run
    takes (``unconsumed``, own names) is left out. Call it right after the step: it takes
    the step's marks.
    """
    marks = take_output_marks()
    due = set(names) if first else set(names) - latched
    if set(outputs) != due:
        missing = sorted(due - set(outputs))
        extra = sorted(set(outputs) - due)
        once = sorted(set(extra) & latched)
        why = f"; {once} are latched: due at the first activation only" if once else ""
        raise StepContractError(f"node {node} at tick {tick.index} returned the wrong topics "
                                f"(missing {missing}, undeclared {extra}{why})")
    items = []
    when = stamp(tick)
    for own, msg in outputs.items():
        if not isinstance(msg, declared[own]):
            raise StepContractError(f"node {node} returned {type(msg).__name__} on {own}, "
                                    f"declared {declared[own].__name__}")
        mark = marks.get(id(msg)) if marks is not None else None
        if mark is not None and mark[0] is not msg:
            mark = None
        if mark is not None and mark[2] and own in unconsumed:
            continue
        header = getattr(msg, "header", None)
        if header is not None and hasattr(header, "stamp"):
            header.stamp = when
        elif isinstance(msg, TFMessage):
            for transform in msg.transforms:
                transform.header.stamp = when
        if mark is not None:
            if mark[1] is not None and header_first(type(msg)):
                items.append((names[own], stamped(when, mark[1])))
                continue
            if tails is not None:
                items.append((names[own], tails.encode(own, msg)))
                continue
        items.append((names[own], encode(msg)))
    items.sort()
    return items


def output_digest(tick: int, items: Iterable[tuple[str, bytes]]) -> bytes:
    """sha256 over (topic, tick, length, bytes) of one activation's outputs, in topic order."""
    h = hashlib.sha256()
    for topic, data in items:
        h.update(topic.encode())
        h.update(struct.pack("<qQ", tick, len(data)))
        h.update(data)
    return h.digest()


class RunDigest:
    """The run digest: sha256 over (tick, node, output digest) in schedule order."""

    def __init__(self) -> None:
        self._hash = hashlib.sha256()

    def add(self, tick: int, node: str, node_digest: bytes) -> None:
        """Fold in one node's activation; call in schedule order."""
        self._hash.update(struct.pack("<q", tick))
        self._hash.update(node.encode())
        self._hash.update(node_digest)

    def hexdigest(self) -> str:
        """The digest so far, as hex."""
        return self._hash.hexdigest()


class SharedDecoder:
    """One decoded message per sample for the consumers in one process that share inputs
    (``StepNode.shares_inputs``): every history of a topic is handed the very bytes object
    that arrived (``runtime.shared_transport``, the in-process loop), so those bytes name the
    sample; the newest few are kept with their message (keeping the bytes keeps their id)."""

    KEEP = 8

    def __init__(self) -> None:
        self._recent: dict[int, tuple[bytes, type, Any]] = {}

    def decode(self, data: bytes, msg_type: type) -> Any:
        """The message of ``data``, decoded once while it is among the newest samples."""
        hit = self._recent.get(id(data))
        if hit is not None and hit[0] is data and hit[1] is msg_type:
            return hit[2]
        msg = decode(data, msg_type)
        self._recent[id(data)] = (data, msg_type, msg)
        if len(self._recent) > self.KEEP:
            del self._recent[next(iter(self._recent))]
        return msg


SHARED_DECODER = SharedDecoder()  # this process's


class InputHistory:
    """Samples of one input (producer tick, message), from which the schedule's pick is made."""

    def __init__(self, topic: str, msg_type: type, shared: SharedDecoder | None = None):
        self.topic = topic
        self.msg_type = msg_type
        self.samples: deque[tuple[int, Any]] = deque()
        self._wanted = None  # () -> Schedule.wanted_samples of a windowed consumer's edge
        self.shared = shared  # where a consumer that only reads its inputs decodes

    def keep_for(self, schedule, edge) -> None:
        """Keep only what the consumer of ``edge`` can still take in its window
        (``Schedule.wanted_samples``, read at each sample: a window a client opens or closes
        mid-run counts from then on): a dormant node, before its robot enters or after it
        left, never takes a sample and so would keep every one."""
        if edge.consumer in schedule.windows:
            self._wanted = lambda: schedule.wanted_samples(edge)

    def push_bytes(self, tick: int, data: bytes) -> None:
        """Add a serialised sample; it is deserialised only if a step ever takes it (slow
        consumers skip most samples of a fast producer). A windowed consumer's sample that
        no activation in its window can take is not kept (``keep_for``)."""
        if self._wanted is not None and (span := self._wanted()) is not None:
            first, last = span
            if last is not None and tick > last:  # after its window: never taken
                while self.samples and self.samples[-1][0] > last:
                    self.samples.pop()
                return
            if first is None:  # not opened yet: only the newest may be wanted where it opens
                self.samples.clear()
            elif tick < first:  # before its window's first sample: never taken
                self.samples.clear()
                return
        self.samples.append((tick, data))

    def has(self, tick: int) -> bool:
        """Whether the sample of ``tick`` (or a later one) has arrived."""
        return bool(self.samples) and self.samples[-1][0] >= tick

    def take_raw(self, tick: int) -> bytes:
        """The CDR bytes of the sample of exactly ``tick`` (it must never have been decoded),
        dropping older ones: what a feeder forwards unchanged."""
        while self.samples and self.samples[0][0] < tick:
            self.samples.popleft()
        if not self.samples or self.samples[0][0] != tick:
            have = [t for t, _ in self.samples]
            raise LookupError(f"{self.topic}: no sample of tick {tick} (have {have})")
        return self.samples[0][1]

    def take(self, tick: int) -> Any:
        """The sample of exactly ``tick``, dropping older ones (they can never be needed again)."""
        while self.samples and self.samples[0][0] < tick:
            self.samples.popleft()
        if not self.samples or self.samples[0][0] != tick:
            have = [t for t, _ in self.samples]
            raise LookupError(f"{self.topic}: no sample of tick {tick} (have {have})")
        sample = self.samples[0][1]
        if isinstance(sample, bytes):  # the same bytes every transport delivers
            sample = (decode(sample, self.msg_type) if self.shared is None
                      else self.shared.decode(sample, self.msg_type))
            self.samples[0] = (tick, sample)
        return sample
