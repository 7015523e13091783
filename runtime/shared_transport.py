"""One transport session shared by the nodes packed into one process.

Each packed node's runtime gets a ``TransportView``: its publishers are the session's own,
and its subscriptions are views of one session subscription per topic, so a topic two
packed nodes consume (the world state a lidar and a camera both render) is taken once and
handed to both. The process makes one wait for all of them (``SharedTransport.pump``);
each runtime then takes what arrived for it without blocking.
"""

from __future__ import annotations

from runtime.protocol import STATUS_TOPIC
from runtime.transport.base import Publisher, Received, Subscription, Transport

SHARED_DEPTH = 1000  # one reader serves consumers of different rates: keep enough for all


class SharedTransport:
    """Multiplexes one transport session between several runtimes."""

    def __init__(self, base: Transport):
        self.base = base
        self._subs: dict[str, Subscription] = {}
        self._views: dict[str, list[TransportView]] = {}
        self._status: Publisher | None = None

    def view(self) -> TransportView:
        """A transport for one packed runtime."""
        return TransportView(self)

    def subscribe(self, view: TransportView, topic: str, msg_type: type,
                  latched: bool) -> Subscription:
        """The session's subscription to ``topic`` (made once), delivering to ``view`` too."""
        if topic not in self._subs:
            self._subs[topic] = self.base.subscription(topic, msg_type, SHARED_DEPTH, latched)
        self._views.setdefault(topic, []).append(view)
        return self._subs[topic]

    def pump(self, timeout_ns: int) -> int:
        """One wait on the session; hand every message to the views of its topic."""
        received = self.base.wait(timeout_ns)
        for rec in received:
            for view in self._views.get(rec.topic, ()):
                view.inbox.append(rec)
        return len(received)

    def close(self) -> None:
        """Close the session."""
        self.base.close()


class TransportView(Transport):
    """What one packed runtime sees: its own publishers, shared subscriptions."""

    def __init__(self, shared: SharedTransport):
        self.shared = shared
        self.inbox: list[Received] = []

    def publisher(self, topic: str, msg_type: type, depth: int,
                  latched: bool = False) -> Publisher:
        """A publisher of the shared session; the packed runtimes share one on
        /cosim/status (one DDS writer, not one per node, and their reports in one order)."""
        if topic != STATUS_TOPIC:
            return self.shared.base.publisher(topic, msg_type, depth, latched)
        if self.shared._status is None:
            self.shared._status = self.shared.base.publisher(topic, msg_type, depth, latched)
        return self.shared._status

    def subscription(self, topic: str, msg_type: type, depth: int,
                     latched: bool = False) -> Subscription:
        """This runtime's share of the session's subscription to ``topic``."""
        return self.shared.subscribe(self, topic, msg_type, latched)

    def wait(self, timeout_ns: int) -> list[Received]:
        """What arrived for this runtime since the last call (never blocks: the process
        waits once for all its runtimes, in ``SharedTransport.pump``)."""
        taken, self.inbox = self.inbox, []
        return taken

    def publisher_nodes(self, topic: str) -> list[str] | None:
        """The shared session's view of the ROS graph."""
        return self.shared.base.publisher_nodes(topic)

    def close(self) -> None:
        """The session is closed once, by its owner."""
