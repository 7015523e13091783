"""A swarm run's outputs: per-robot metrics and totals (manifest and summary), and the
picture of every robot's path in its own colour (report.png).

The numbers are the world node's ground truth (nodes/physics/swarm.py metrics, keyed
``ROBOT/...``): whether and when each robot reached its goal, the length of the path it
drove, and its collision events with obstacles and with other robots.
"""

from __future__ import annotations

import math
from pathlib import Path
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


def swarm_figure(scenario, bag: Path, outcome):
    """The arena from above with every robot's driven path in its own colour, its start
    (square), goal (star, tolerance circle) and where it ended (dot)."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    from orchestrator.outputs.picture import draw_obstacles, load_world, read_bag, title
    from plan.robots import namespaced

    layout = scenario.robots
    topics = tuple(namespaced(r, "/odom") for r in layout.names)
    data = read_bag(Path(bag), topics)
    world = load_world(scenario.world)
    colours = colormaps["tab20" if len(layout.names) > 10 else "tab10"]
    fig = Figure(figsize=(11, 10))
    ax = fig.add_subplot(1, 1, 1)
    draw_obstacles(ax, world)
    for i, (robot, topic) in enumerate(zip(layout.robots, topics, strict=True)):
        colour = colours(i % colours.N)
        odom = data.messages.get(topic, [])
        xy = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for _, m in odom])
        if len(xy):
            ax.plot(xy[:, 0], xy[:, 1], color=colour, lw=2, zorder=3, label=robot.name)
            ax.plot(xy[-1, 0], xy[-1, 1], "o", color=colour, markeredgecolor="black",
                    ms=6, zorder=5)
        ax.plot(robot.start[0], robot.start[1], "s", color=colour, markeredgecolor="black",
                ms=8, zorder=4)
        ax.plot(robot.goal[0], robot.goal[1], "*", color=colour, markeredgecolor="black",
                ms=14, zorder=4)
        ax.add_patch(Circle(robot.goal[:2], layout.position_tolerance, fill=False, ls="--",
                            edgecolor=colour, zorder=4))
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, alpha=0.25)
    if len(layout.names) <= 20:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    swarm = swarm_entry(scenario, getattr(getattr(outcome, "result", None), "metrics", {}) or {})
    sub = "square: start, star: goal, dot: end"
    if swarm is not None:
        t = swarm["totals"]
        sub = (f"{t['arrived']} of {t['robots']} robots reached their goals; collisions: "
               f"{t['collisions_obstacles']} with obstacles, {t['collisions_robots']} between "
               f"robots; {sub}")
    fig.suptitle(title(scenario, outcome), fontsize=13)
    ax.set_title(sub, fontsize=9, color="#444444")
    if not math.isfinite(ax.get_xlim()[0]):
        ax.autoscale()
    return fig
