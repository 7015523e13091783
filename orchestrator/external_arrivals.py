"""Messages that arrive from outside a run, waiting for the external node's next tick (no
ROS import here: the orchestrator creates them before it forks its node processes)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any


class Arrivals:
    """Messages from outside, per topic, waiting for the next activation (thread-safe)."""

    def __init__(self, topics: dict[str, type]):
        self.topics = dict(topics)
        self._lock = threading.Lock()
        self._waiting: dict[str, Any] = {}
        self.count = 0

    def put(self, topic: str, msg: Any) -> None:
        """A message arrived; it enters at the node's next activation (the last per topic)."""
        if topic not in self.topics:
            raise KeyError(f"{topic} is not an external topic of this run "
                           f"({', '.join(sorted(self.topics))})")
        if not isinstance(msg, self.topics[topic]):
            raise TypeError(f"{topic} takes {self.topics[topic].__name__}, "
                            f"not {type(msg).__name__}")
        with self._lock:
            self._waiting[topic] = msg
            self.count += 1

    def take(self, tick: int) -> dict[str, Any]:
        """Everything that arrived since the last take (enters at ``tick``)."""
        with self._lock:
            taken, self._waiting = self._waiting, {}
        return taken


Replay = Callable[[int], dict[str, Any]]
"""tick -> the recorded external inputs of that tick (a replay)."""
