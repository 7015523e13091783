"""Bounded per-channel queues between a producer that must never wait and a consumer thread.

``put`` never blocks: each channel keeps its newest ``depth`` items, dropping (and counting)
the oldest when full. ``take`` hands the consumer everything queued, oldest first per
channel, waiting up to a timeout when nothing is there.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable, Hashable
from typing import Any


class BoundedChannels:
    """Newest-``depth`` queues per channel, drop-oldest, with drop counts (thread-safe)."""

    def __init__(self, depth: int, on_first: Callable[[], None] | None = None):
        if depth < 1:
            raise ValueError("depth must be at least 1")
        self.depth = depth
        self._queues: dict[Hashable, deque] = {}
        self._lock = threading.Lock()
        self._ready = threading.Condition(self._lock)
        self._pending = 0
        self._on_first = on_first  # called (outside the lock) when the first item is queued
        self.dropped: dict[Hashable, int] = {}
        self.offered = 0
        self.closed = False

    def put(self, channel: Hashable, item: Any) -> None:
        """Queue ``item`` on ``channel``; when full, the channel's oldest item is dropped."""
        with self._lock:
            if self.closed:
                return
            queue = self._queues.get(channel)
            if queue is None:
                queue = self._queues[channel] = deque()
            if len(queue) >= self.depth:
                queue.popleft()
                self.dropped[channel] = self.dropped.get(channel, 0) + 1
            else:
                self._pending += 1
            queue.append(item)
            self.offered += 1
            first = self._pending == 1
            if first:  # the consumer takes everything at once: wake it once per batch
                self._ready.notify()
        if first and self._on_first is not None:
            self._on_first()

    def take(self, timeout_s: float | None = None) -> list[tuple[Hashable, Any]]:
        """Everything queued as (channel, item), oldest first per channel; waits up to
        ``timeout_s`` for something (None: do not wait)."""
        with self._lock:
            if not self._pending and timeout_s and not self.closed:
                self._ready.wait(timeout_s)
            out = [(channel, item) for channel, queue in self._queues.items() for item in queue]
            for queue in self._queues.values():
                queue.clear()
            self._pending = 0
        return out

    def close(self) -> None:
        """Accept nothing more and wake a waiting consumer."""
        with self._lock:
            self.closed = True
            self._ready.notify_all()

    def dropped_total(self) -> int:
        """Items dropped over all channels."""
        with self._lock:
            return sum(self.dropped.values())
