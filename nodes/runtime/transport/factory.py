"""Open the transport a scenario names (kept apart from the seam, ``base``, so that the
backends import the seam and nothing imports back)."""

from __future__ import annotations

from nodes.runtime.transport.base import Transport
from plan.options import TransportSettings


def create_transport(settings: TransportSettings, participant: str) -> Transport:
    """The transport of ``settings`` ('ros2' or 'zenoh') for one participant (node) name."""
    if settings.kind == "ros2":
        from nodes.runtime.transport.ros2 import Ros2Transport

        return Ros2Transport(participant)
    if settings.kind == "zenoh":
        from nodes.runtime.transport.zenoh import ZenohTransport

        return ZenohTransport(participant, settings)
    raise ValueError(f"transport {settings.kind!r} is not available; use ros2 or zenoh")
