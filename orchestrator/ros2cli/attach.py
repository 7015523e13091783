"""Which ROS domain a cosim-ros2 verb works on: ``--domain`` or ROS_DOMAIN_ID when given,
else the domain of the cosim run going on this machine (its claim says which, and with what
discovery range: ``orchestrator.run_domain.going``), so that a fresh shell sees a run by
itself. With several runs going it takes the newest and names the others; with none, ROS 2's
default (domain 0)."""

from __future__ import annotations

import os
import sys

from orchestrator.run_domain import going


def domain_to_use(given: int | None) -> int | None:
    """The domain for ``given`` (--domain's value): it, or None where ROS_DOMAIN_ID says or
    no run is going; else the run's, its discovery range set for this process, the choice
    said on stderr."""
    if given is not None or os.environ.get("ROS_DOMAIN_ID", "").strip():
        return given
    runs = going()
    if not runs:
        return None
    chosen = runs[0]
    os.environ.update(chosen.environment)
    if len(runs) == 1:
        say(f"attached to ROS domain {chosen.domain}, the cosim run going on this machine: "
            f"{chosen.holder}")
    else:
        others = "; ".join(f"ROS domain {r.domain}: {r.holder}" for r in runs[1:])
        say(f"{len(runs)} cosim runs are going on this machine; attached to the newest, ROS "
            f"domain {chosen.domain}: {chosen.holder}. The others: {others}. Choose one with "
            "--domain ID (or ROS_DOMAIN_ID=ID)")
    return chosen.domain


def say(text: str) -> None:
    """One line on stderr, as cosim-ros2's."""
    print(f"cosim-ros2: {text}", file=sys.stderr)
