"""Messages that arrive from outside a run (a client, a real robot), waiting for the next
step that takes them: the external node's next tick in a lockstep run, a realtime node's
next step. No ROS import here: the orchestrator creates them before it forks its node
processes."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any


class Arrivals:
    """Messages from outside, per topic, waiting for the next activation (thread-safe)."""

    def __init__(self, topics: dict[str, type], what: str = "an external topic of this run"):
        self.topics = dict(topics)
        self.what = what  # what the topics are, for the error naming an unknown one
        self._lock = threading.Lock()
        self._waiting: dict[str, Any] = {}
        self.count = 0

    def put(self, topic: str, msg: Any, merge: Callable[[Any, Any], Any] | None = None) -> Any:
        """A message arrived; it enters at the node's next activation (the last per topic).
        Returns the message it replaced, one that arrived since the last activation and now
        never enters, or None. With ``merge``, one waiting is not replaced: ``merge(waiting,
        msg)`` enters instead (and None is returned)."""
        if topic not in self.topics:
            raise KeyError(f"{topic} is not {self.what} "
                           f"({', '.join(sorted(self.topics))})")
        if not isinstance(msg, self.topics[topic]):
            raise TypeError(f"{topic} takes {self.topics[topic].__name__}, "
                            f"not {type(msg).__name__}")
        with self._lock:
            replaced = self._waiting.get(topic)
            if merge is not None and replaced is not None:
                msg, replaced = merge(replaced, msg), None
            self._waiting[topic] = msg
            self.count += 1
        return replaced

    def take(self, tick: int | None = None) -> dict[str, Any]:
        """Everything that arrived since the last take (enters at ``tick``)."""
        with self._lock:
            taken, self._waiting = self._waiting, {}
        return taken


Replay = Callable[[int], dict[str, Any]]
"""tick -> the recorded external inputs of that tick (a replay)."""
