"""The transport seam: publish and take serialised ROS 2 messages, nothing else.

Step nodes never see a transport; the runtime and the orchestrator master use this
interface, so a second backend (zenoh) only has to implement these three classes.
All payloads are CDR bytes as produced by ``rclpy.serialization.serialize_message``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass


@dataclass
class Received:
    """One message taken from a subscription: its bytes and the publisher's sequence number."""

    topic: str
    data: bytes
    sequence: int | None


class Publisher(ABC):
    """Publishes serialised messages on one topic."""

    topic: str

    @abstractmethod
    def publish(self, data: bytes) -> None:
        """Send one serialised message."""

    @abstractmethod
    def matched(self) -> int:
        """How many subscriptions are matched (discovery done)."""


class Subscription(ABC):
    """Receives serialised messages on one topic."""

    topic: str

    @abstractmethod
    def matched(self) -> int:
        """How many publishers are matched (discovery done)."""


class Transport(ABC):
    """One participant: creates publishers and subscriptions and waits for messages."""

    @abstractmethod
    def publisher(self, topic: str, msg_type: type, depth: int,
                  latched: bool = False) -> Publisher:
        """A reliable publisher keeping ``depth`` samples; ``latched`` (transient-local) keeps
        them for subscriptions that match later, as /tf_static's publisher does."""

    @abstractmethod
    def subscription(self, topic: str, msg_type: type, depth: int,
                     latched: bool = False) -> Subscription:
        """A reliable subscription keeping ``depth`` samples; ``latched`` also receives what a
        transient-local (latched) publisher sent before the subscription matched."""

    @abstractmethod
    def wait(self, timeout_ns: int) -> list[Received]:
        """Block up to ``timeout_ns`` for messages; return every message available, in order."""

    @abstractmethod
    def close(self) -> None:
        """Release the participant."""

    def publisher_nodes(self, topic: str) -> list[str] | None:
        """The node names of ``topic``'s publishers in the ROS graph; None where the
        transport has no graph to ask (runtime.intruders)."""
        return None
