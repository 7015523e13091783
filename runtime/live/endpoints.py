"""What a live endpoint serves, independent of who runs it (the orchestrator or a realtime
node): the topics a client may watch, the topics it may drive, and the services it may call.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from plan.timeutil import NS_PER_S
from runtime.protocol import CLOCK_TOPIC, decode_clock


class ServiceUnavailable(RuntimeError):
    """A service call that could not be served (no such service, the run is not taking
    calls, a time-out); the text says which."""


class Services(Protocol):
    """Services a client may call (simulation control)."""

    def types(self) -> dict[str, type]:
        """Service name -> its rclpy service class."""

    def call(self, name: str, request: Any, timeout_s: float) -> Any:
        """Serve one call and return the response; ServiceUnavailable when it cannot."""


class Actions(Protocol):
    """Action servers a client may send goals to (SimulateSteps, NavigateToPose)."""

    def types(self) -> dict[str, type]:
        """Action name -> its rclpy action class."""

    def run_goal(self, name: str, goal: Any, on_feedback: Callable[[Any], None],
                 cancelled: Callable[[], bool], timeout_s: float) -> tuple[int, Any]:
        """Send one goal, pass each feedback message to ``on_feedback``, cancel it once
        ``cancelled()``; return (GoalStatus status, result message). ServiceUnavailable when
        it cannot be sent or accepted."""


class Inbox(Protocol):
    """Where messages from clients enter the run (``orchestrator``'s Arrivals has this shape)."""

    topics: dict[str, type]

    def put(self, topic: str, msg: Any) -> None:
        """Take one message; KeyError for a topic it does not take, TypeError for a wrong one."""


@dataclass
class Catalog:
    """What an endpoint offers: topics to watch (with their message classes), an inbox for
    client messages, services, and the words that explain a refusal."""

    topics: dict[str, type]
    inbox: Inbox | None = None
    services: Services | None = None
    actions: Actions | None = None
    no_inbox_text: str = "this run takes no messages from outside"
    inbox_what: str = "a topic this run takes from outside"
    latched: frozenset[str] = frozenset()  # sent once (/tf_static): a late client gets the last
    services_ready: threading.Event | None = None  # set once services come (None: no later)
    header_types: set[type] = field(default_factory=set)

    def __post_init__(self) -> None:
        self.header_types = {cls for cls in self.topics.values()
                             if next(iter(cls.get_fields_and_field_types()), "") == "header"
                             and cls.get_fields_and_field_types()["header"] == "std_msgs/Header"}

    def stamp_of(self, topic: str, data: bytes, fallback_ns: int) -> int:
        """A message's time: /clock's value, the header stamp of a stamped type (read from
        the CDR bytes: int32 sec, uint32 nanosec after the 4-byte encapsulation), else
        ``fallback_ns`` (the latest clock)."""
        if topic == CLOCK_TOPIC:
            return decode_clock(data)
        if self.topics.get(topic) in self.header_types and len(data) >= 12:
            sec = int.from_bytes(data[4:8], "little", signed=True)
            nanosec = int.from_bytes(data[8:12], "little")
            return sec * NS_PER_S + nanosec
        return fallback_ns


Offer = Callable[[str, bytes], None]
"""(topic, CDR bytes): a message of the run, offered to the endpoints (never blocks)."""
