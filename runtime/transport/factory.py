"""Open the transport a scenario names (kept apart from the seam, ``base``, so that the
backends import the seam and nothing imports back)."""

from __future__ import annotations

from plan.options import TransportSettings
from runtime.transport.base import Transport


def create_transport(settings: TransportSettings, participant: str) -> Transport:
    """The transport of ``settings`` ('ros2' or 'zenoh') for one participant (node) name."""
    if settings.kind == "ros2":
        from runtime.transport.ros2 import Ros2Transport

        return Ros2Transport(participant)
    if settings.kind == "zenoh":
        from runtime.transport.zenoh import ZenohTransport

        return ZenohTransport(participant, settings)
    raise ValueError(f"transport {settings.kind!r} is not available; use ros2 or zenoh")
