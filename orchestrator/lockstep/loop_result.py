"""What a run produced, and the goal test every driver applies to it (no transport needed:
the orchestrator imports this before it forks node processes)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class LoopResult:
    """What a tick loop produced: digest, ticks run, per-node metrics, early stop or not."""

    digest: str
    ticks: int
    metrics: dict[str, dict[str, float]] = field(default_factory=dict)
    stopped_early: bool = False
    step_ns: dict[str, list[int]] = field(default_factory=dict)  # in-process: [n, total, worst]
    notes: list = field(default_factory=list)  # in-process: runtime.notes.Note, in order


def goal_reached(metrics: dict[str, dict[str, float]],
                 trailing: frozenset[str] = frozenset()) -> bool:
    """Whether the goal is reached: as a navigator reports it ('goal_reached'), or, when no
    node reports that, as physics sees it in ground truth ('arrived'). ``trailing`` nodes
    (whose reports may trail the others) are not consulted."""
    metrics = {n: m for n, m in metrics.items() if n not in trailing}
    swarm = [m["swarm_goal"] for m in metrics.values() if "swarm_goal" in m]
    if swarm:  # many robots: the world node knows whether enough reached theirs
        return any(v >= 1 for v in swarm)
    claimed = [m["goal_reached"] for m in metrics.values() if "goal_reached" in m]
    if claimed:
        return any(v >= 1 for v in claimed)
    return any(m.get("arrived", 0) >= 1 for m in metrics.values())
