"""Publishers that are not the scenario's: found in the ROS graph, named with the remedy.

Every topic of a lockstep run has exactly one publisher, the scenario's node, whose
messages are counted by their sequence numbers. A publisher from outside (a teleop left
running, another run on the same ROS domain) breaks the count: nothing was lost, but its
messages would change the run's inputs, so the run stops, and says whose they were.
"""

from __future__ import annotations

import time

OWN_PREFIX = "cosim_"  # every participant of a cosim run names its ROS node cosim_<...>
LOOK_S = 1.0  # how long the graph may take to name a publisher whose messages arrived
REMEDY = ("stop that node, or give the run a ROS domain of its own (cosim-orchestrate takes "
          "one unless ROS_DOMAIN_ID or --domain pins it; `ROS_DOMAIN_ID=<id> ros2 node list` "
          "shows who is on a domain)")


def publisher_nodes(transport, topic: str) -> list[str] | None:
    """The node names of ``topic``'s publishers in the graph (None: not a graph transport)."""
    graph = getattr(transport, "publisher_nodes", None)
    if graph is None:
        return None
    try:
        return graph(topic)
    except Exception:  # noqa: BLE001 - a closing or foreign transport: nothing to tell
        return None


def strangers(names: list[str]) -> list[str]:
    """The publishers of a cosim topic that are not the run's: a name not a cosim node's, or
    a cosim node's name twice (another run of a scenario on the same domain)."""
    own = [n for n in names if n.rsplit("/", 1)[-1].startswith(OWN_PREFIX)]
    out = [n for n in names if n not in own]
    out += sorted({n for n in own if own.count(n) > 1})
    return out


def describe(topic: str, names: list[str]) -> str:
    """'a publisher that is not the scenario's writes to /cmd_vel: node /teleop; ...'."""
    listed = ", ".join(f"node {n}" + (" (a node of another cosim run?)"
                                      if n.rsplit("/", 1)[-1].startswith(OWN_PREFIX) else "")
                       for n in names)
    many = "publishers that are not the scenario's write" if len(names) > 1 else \
        "a publisher that is not the scenario's writes"
    return f"{many} to {topic}: {listed}"


def explain_gap(transport, topic: str, text: str) -> str:
    """The text of a sequence gap on ``topic``: the intruder named, nothing lost and the
    remedy when the graph shows one; else ``text`` as it was."""
    deadline = time.monotonic() + LOOK_S
    while True:
        names = publisher_nodes(transport, topic)
        if names is None:
            return text
        found = strangers(names)
        if found and not any(n.endswith("_NODE_NAME_UNKNOWN_") for n in found):
            return (f"{describe(topic, found)}. Nothing was lost: the run stopped because "
                    "messages from outside the scenario would change its inputs (one came "
                    f"among the scenario's numbered ones). Remedy: {REMEDY}")
        if time.monotonic() >= deadline:
            if found:
                return f"{describe(topic, found)} ({text}?). Remedy: {REMEDY}"
            return text
        time.sleep(0.05)


def graph_strangers(transport, topics: list[str]) -> list[str]:
    """For each topic with publishers that are not the run's, what ``describe`` says.

    A publisher whose endpoint was discovered before its participant's node names arrived is
    listed as _NODE_NAME_UNKNOWN_: the graph is asked again (for up to LOOK_S) until it names
    it, rather than taking it for nobody (a teleop already running was missed so when the run
    became ready quickly)."""
    deadline = time.monotonic() + LOOK_S
    while True:
        found, unnamed = [], False
        for topic in topics:
            names = publisher_nodes(transport, topic)
            if names is None:
                return []
            unnamed |= any(n.endswith("_NODE_NAME_UNKNOWN_") for n in names)
            names = [n for n in names if not n.endswith("_NODE_NAME_UNKNOWN_")]
            if strange := strangers(names):
                found.append(describe(topic, strange))
        if found or not unnamed or time.monotonic() >= deadline:
            return found
        time.sleep(0.05)
