"""A swarm run's per-robot metrics and totals, for the manifest and the summary.

The numbers are the world node's ground truth (nodes/physics/swarm.py metrics, keyed
``ROBOT/...``): whether and when each robot reached its goal, the length of the path it
drove, and its collision events with obstacles and with other robots.
"""

from __future__ import annotations

from typing import Any

import numpy as np

PER_ROBOT = ("arrived", "time_to_goal", "path_length", "collisions_obstacles",
             "collisions_robots")
ROWS_SHOWN = 16  # robots listed in the terminal summary; the manifest has them all


def swarm_entry(scenario, metrics_by_node: dict[str, dict[str, float]]) -> dict[str, Any] | None:
    """The manifest's ``swarm`` section: {robots: {name: {...}}, totals: {...}}; None
    when the scenario has no robots: section or no node reported them."""
    layout = getattr(scenario, "robots", None)
    if layout is None:
        return None
    world = next((m for m in metrics_by_node.values() if "swarm_goal" in m), None)
    if world is None:
        return None
    robots = {}
    for name in layout.names:
        entry = {key: world.get(f"{name}/{key}") for key in PER_ROBOT}
        entry["arrived"] = bool(entry["arrived"])
        robots[name] = entry
    times = [r["time_to_goal"] for r in robots.values() if r["time_to_goal"] is not None]
    totals = {"robots": len(robots), "arrived": sum(r["arrived"] for r in robots.values()),
              "needed": layout.needed,
              "collisions_obstacles": int(world.get("collisions_obstacles", 0)),
              "collisions_robots": int(world.get("collisions_robots", 0)),
              "path_length": float(world.get("path_length", 0.0)),
              "last_time_to_goal": max(times) if times else None,
              "mean_time_to_goal": float(np.mean(times)) if times else None}
    return {"robots": robots, "totals": totals}


def swarm_rows(swarm: dict[str, Any]) -> list[tuple[str, str]]:
    """Summary rows: the totals, then a line per robot (the first ROWS_SHOWN)."""
    t = swarm["totals"]
    rows = [("robots reached", f"{t['arrived']} of {t['robots']} (needed {t['needed']})"),
            ("collision kinds", f"{t['collisions_obstacles']} with obstacles, "
                           f"{t['collisions_robots']} between robots"),
            ("path length", f"{t['path_length']:.2f} m in all")]
    if t["last_time_to_goal"] is not None:
        rows.append(("time to goal", f"mean {t['mean_time_to_goal']:.2f} s, last "
                                     f"{t['last_time_to_goal']:.2f} s"))
    for name, r in list(swarm["robots"].items())[:ROWS_SHOWN]:
        when = f"goal at {r['time_to_goal']:.2f} s" if r["arrived"] else "goal not reached"
        rows.append((name, f"{when}, {r['path_length'] or 0:.2f} m, collisions "
                           f"{int(r['collisions_obstacles'] or 0)} obstacle / "
                           f"{int(r['collisions_robots'] or 0)} robot"))
    if len(swarm["robots"]) > ROWS_SHOWN:
        rows.append(("...", f"{len(swarm['robots']) - ROWS_SHOWN} more robots in manifest.json"))
    return rows
