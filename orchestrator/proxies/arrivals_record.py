"""The record of what entered a run from outside: each message the external node took, at
the tick it took it, as it arrived (its own stamp, before the node re-stamps its outputs).

The external node's outputs repeat the latest message of every topic at every activation,
so they cannot tell a new arrival from a held one; this record can. It is written into the
external node's part next to its outputs, under ``/cosim/arrivals/<topic>`` (the bag keeps
it like any topic), and is no part of the digest: the outputs it causes are. ``--replay``
reads it back (``orchestrator.replay``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from plan.roles import NodeRole
from runtime.cdr.encode import encode
from runtime.recording import PartWriter

ARRIVALS_PREFIX = "/cosim/arrivals"


def arrival_topic(topic: str) -> str:
    """Where the arrivals of external topic ``topic`` are recorded."""
    return ARRIVALS_PREFIX + topic


def external_topic(recorded: str) -> str | None:
    """The external topic a recorded arrivals topic is of (None: not an arrivals topic)."""
    if recorded.startswith(ARRIVALS_PREFIX + "/"):
        return recorded[len(ARRIVALS_PREFIX):]
    return None


def arrival_items(inputs: dict[str, Any]) -> list[tuple[str, bytes]]:
    """One activation's arrivals as (recorded topic, CDR bytes), sorted by topic."""
    return sorted((arrival_topic(topic), encode(msg)) for topic, msg in inputs.items())


def arrival_topics(scenario) -> dict[str, type]:
    """Recorded arrivals topic -> message class, for the scenario's external node (the bag
    declares them)."""
    return {arrival_topic(topic): cls
            for plan in scenario.nodes.values() if plan.role is NodeRole.ORCHESTRATOR
            for topic, cls in plan.outputs.items()}


def recording(take: Callable[[int], dict] | None, writer: PartWriter | None
              ) -> Callable[[int], dict] | None:
    """``take`` (tick -> what enters), also writing what it gives into the external node's
    part ``writer`` (an in-process run, where no ExternalSource records it)."""
    if take is None or writer is None:
        return take

    def take_and_record(tick: int) -> dict:
        inputs = take(tick)
        if inputs:
            writer.write(tick, arrival_items(inputs))
        return inputs

    return take_and_record
