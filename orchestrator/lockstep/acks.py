"""The acknowledgements a run is owed, and the run digest folded from them in schedule order.

The master may publish ``/clock`` for a few ticks ahead of the last finished one (the
pipeline window), and a leaf node such as a camera may still be rendering tick ``k``
while physics runs ``k + 1``; so acknowledgements arrive out of tick order. Two ordered
views come out of the book whatever the arrival order:

- *decided* ticks: every due node that may not trail has acknowledged, so the stop decision
  (goal reached) can be taken for that tick, exactly as the in-process run takes it;
- *folded* ticks: every due node has acknowledged; the digest is folded tick by tick and,
  within a tick, in the schedule's order, so it cannot depend on timing.
"""

from __future__ import annotations

from collections import deque

from plan.schedule import Schedule
from runtime.exchange import RunDigest
from runtime.protocol import Done


class AckBook:
    """(tick, node) acknowledgements still owed, and what has come in, in tick order."""

    def __init__(self, sched: Schedule, trailing: frozenset[str] = frozenset()):
        self.sched = sched
        self.trailing = trailing
        self.owed: dict[str, deque[int]] = {n: deque() for n in sched.periods}
        self.deadline: dict[str, float] = {}  # of each node's oldest owed tick
        self.received: dict[int, dict[str, Done]] = {}  # from the tick's clock until both
        # decided and folded: an undecided tick has an entry exactly when it was expected
        self.next_fold = 0
        self.next_decided = 0
        self.end: int | None = None
        self._digest = RunDigest()

    def expect(self, tick: int, now: float, limit_s: float) -> None:
        """The nodes due at ``tick`` each owe an acknowledgement; a node's deadline runs
        ``limit_s`` from when the tick is the oldest it owes (it cannot start it earlier)."""
        for name in self.sched.due(tick):
            if not self.owed[name]:
                self.deadline[name] = now + limit_s
            self.owed[name].append(tick)
        self.received[tick] = {}

    def record(self, done: Done, now: float, limit_s: float) -> bool:
        """File an activation reported done; False when it was not owed (a duplicate, a
        stray, or a tick after the end of a run stopped early)."""
        owed = self.owed.get(done.node)
        if not owed or done.tick not in owed:
            return False
        owed.remove(done.tick)
        if owed:
            self.deadline[done.node] = now + limit_s
        self.received[done.tick][done.node] = done
        return True

    def oldest_owed(self) -> dict[str, int]:
        """Each node that owes something: the oldest tick it owes."""
        return {name: ticks[0] for name, ticks in self.owed.items() if ticks}

    def late(self, now: float) -> list[tuple[int, str]]:
        """(tick, node) whose deadline has passed."""
        return [(ticks[0], name) for name, ticks in self.owed.items()
                if ticks and self.deadline[name] < now]

    def pending(self) -> bool:
        """Whether any acknowledgement is still owed."""
        return any(self.owed.values())

    def may_start(self, tick: int, window: int) -> bool:
        """Whether ``tick`` may start while acknowledgements are owed: no node would then be
        more than ``window`` ticks behind (a trailing node: ``window`` plus its period - 1)."""
        for name, ticks in self.owed.items():
            if ticks:
                slack = self.sched.periods[name] if name in self.trailing else 1
                if tick - ticks[0] >= slack + window - 1:
                    return False
        return True

    def take_decided(self) -> tuple[int, dict[str, Done]] | None:
        """The next tick in order whose non-trailing acknowledgements are all in, with them."""
        tick = self.next_decided
        got = self.received.get(tick)
        if got is None or (self.end is not None and tick >= self.end):
            return None
        for name in self.sched.due(tick):
            if name not in got and name not in self.trailing:
                return None
        self.next_decided += 1
        if tick < self.next_fold:
            del self.received[tick]
        return tick, {n: s for n, s in got.items() if n not in self.trailing}

    def take_folded(self) -> list[tuple[int, dict[str, Done]]]:
        """Fold every tick that is complete, in order; return them with their reports."""
        folded = []
        while self.next_fold in self.received and (self.end is None or self.next_fold < self.end):
            tick = self.next_fold
            got, due = self.received[tick], self.sched.due(tick)
            if len(got) < len(due):
                break
            for name in due:
                self._digest.add(tick, name, bytes.fromhex(got[name].digest))
            if tick < self.next_decided:
                del self.received[tick]
            folded.append((tick, got))
            self.next_fold += 1
        return folded

    def close(self, end: int) -> None:
        """The run ends before ``end``: acknowledgements of later ticks are no longer owed."""
        self.end = end
        for ticks in self.owed.values():
            while ticks and ticks[-1] >= end:
                ticks.pop()

    def hexdigest(self) -> str:
        """The digest of every tick folded so far."""
        return self._digest.hexdigest()
