"""A digital twin's plan: where the real robot's rosbridge server is, and the topic map.

The scenario's ``twin:`` section (or ``--twin ws://HOST:PORT``) names the robot; its
``subscribe`` map says which robot topics enter the run under which of the run's external
topics (the robot's ``/odom`` as ``/real/odom``: the physics node mirrors the robot from it),
its ``publish`` map which run topics go back to the robot under which names. Both are
checked when the scenario loads: a name that is not in the run is a ScenarioError.
"""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import urlsplit

MIRROR_TOPIC = "/real/odom"
"""The run topic whose odometry the physics node mirrors kinematically."""
MIRROR_JOINTS_TOPIC = "/real/joint_states"
"""The run topic whose joint positions the physics node mirrors with the pose."""


@dataclass(frozen=True)
class TwinAddress:
    """A robot's rosbridge server: ws://HOST:PORT."""

    host: str
    port: int

    @property
    def url(self) -> str:
        """ws://HOST:PORT."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    def __str__(self) -> str:
        return self.url


def parse_twin_url(text: str) -> TwinAddress:
    """``ws://HOST:PORT`` (the port is required: rosbridge_server's usual one is 9090);
    ValueError saying what is wrong and what is accepted."""
    accepted = "ws://HOST:PORT, e.g. ws://192.168.1.20:9090 or ws://127.0.0.1:9190"
    try:
        parts = urlsplit(str(text).strip())
        port = parts.port
    except ValueError as exc:
        raise ValueError(f"twin address {text!r} does not parse ({exc}); give {accepted}") from None
    if parts.scheme != "ws":
        raise ValueError(f"twin address {text!r} is not a ws:// address; give {accepted}")
    if not parts.hostname or port is None or port == 0:
        raise ValueError(f"twin address {text!r} needs a host and a port; give {accepted}")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise ValueError(f"twin address {text!r} has more than a host and port; give {accepted}")
    return TwinAddress(parts.hostname, port)


def twin_problems(twin, external_topics: dict[str, type], run_topics: dict[str, type]
                  ) -> list[tuple[str, str, str]]:
    """(key, problem, accepted) for a topic map naming what the run does not have."""
    problems = []
    if twin.url is not None:
        try:
            parse_twin_url(twin.url)
        except ValueError as exc:
            problems.append(("twin.url", str(exc), "ws://HOST:PORT"))
    for robot, run in twin.subscribe.items():
        if run not in external_topics:
            problems.append((f"twin.subscribe.{robot}", f"{robot} would enter as {run}, which "
                             "is not one of the run's external topics "
                             f"({', '.join(sorted(external_topics)) or 'none'})",
                             f"a topic of the scenario's external: section, e.g. external: "
                             f"{{rate: 50, topics: {{{run}: nav_msgs/msg/Odometry}}}}"))
    seen: dict[str, str] = {}
    for run, robot in twin.publish.items():
        if run not in run_topics:
            problems.append((f"twin.publish.{run}", f"the run has no topic {run} to send back",
                             f"one of {', '.join(sorted(run_topics))}"))
        if robot in seen:
            problems.append((f"twin.publish.{run}", f"{robot} is also where {seen[robot]} "
                             "goes back", "one robot topic per run topic"))
        seen[robot] = run
    return problems
