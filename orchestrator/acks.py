"""The acknowledgements a run is owed, and the run digest folded from them in schedule order.

Acknowledgements may arrive out of tick order (a leaf node such as a camera may still be
rendering tick ``k`` while physics runs ``k + 1``), but the digest is always folded tick by
tick and, within a tick, in the schedule's order, so it cannot depend on timing.
"""

from __future__ import annotations

from nodes.exchange import RunDigest
from orchestrator.schedule import Schedule


class AckBook:
    """(tick, node) pairs still owed, with deadlines; the digest of all that has come in."""

    def __init__(self, sched: Schedule):
        self.sched = sched
        self.owed: dict[tuple[int, str], float] = {}
        self.received: dict[int, dict[str, bytes]] = {}
        self.next_fold = 0
        self._digest = RunDigest()

    def expect(self, tick: int, names: tuple[str, ...], deadline: float) -> None:
        """The due nodes of ``tick`` each owe an acknowledgement by ``deadline``."""
        for name in names:
            self.owed[(tick, name)] = deadline
        self.received.setdefault(tick, {})

    def record(self, tick: int, node: str, digest_hex: str) -> bool:
        """File an acknowledgement; False when it was not owed (a duplicate or a stray)."""
        if self.owed.pop((tick, node), None) is None:
            return False
        self.received[tick][node] = bytes.fromhex(digest_hex)
        self._fold()
        return True

    def _fold(self) -> None:
        while self.next_fold in self.received:
            got = self.received[self.next_fold]
            due = self.sched.due(self.next_fold)
            if len(got) < len(due):
                return
            for name in due:
                self._digest.add(self.next_fold, name, got[name])
            del self.received[self.next_fold]
            self.next_fold += 1

    def blocking(self, before_tick: int | None, leaves: frozenset[str]) -> list[tuple[int, str]]:
        """Owed pairs that must arrive before ``before_tick`` starts (None: all of them).

        A leaf node's acknowledgement may wait until that node is due again.
        """
        if before_tick is None:
            return list(self.owed)
        return [(t, n) for (t, n) in self.owed
                if n not in leaves or self.sched.is_due(n, before_tick)]

    def hexdigest(self) -> str:
        """The digest of every tick folded so far."""
        return self._digest.hexdigest()
