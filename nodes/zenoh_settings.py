"""The zenoh transport's settings passed from the orchestrator to its nodes through the
environment (kept apart from ``transport_zenoh`` so the orchestrator can set them before it
forks node processes, without importing zenoh)."""

from __future__ import annotations

import os

LISTEN_ENV = "COSIM_ZENOH_LISTEN"
ROUTER_CONNECT_ENV = "COSIM_ZENOH_ROUTER_CONNECT"
MIRROR_ENV = "COSIM_ZENOH_MIRROR"


def export_settings(spec) -> None:
    """Put a scenario's ``zenoh:`` section into the environment (variables already set win)."""
    for env, values in ((LISTEN_ENV, spec.listen), (ROUTER_CONNECT_ENV, spec.connect),
                        (MIRROR_ENV, spec.mirror_to_dds)):
        if values:
            os.environ.setdefault(env, ",".join(values))
