"""report.png of a swarm run: the arena from above with every robot's path in its own colour
(orchestrator.outputs.picture draws one robot's run)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from orchestrator.outputs.picture import (
    DPI,
    World,
    add_obstacles,
    draw_obstacles,
    read_bag,
    title,
)
from orchestrator.outputs.swarm import swarm_entry
from plan.robots import namespaced
from plan.run_paths import RunPaths


def write_swarm_png(scenario, run_dir: Path, bag: Path | None, outcome=None) -> Path | None:
    """Draw the swarm's run from its bag into ``<run dir>/report.png``; None without a bag."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if bag is None or not Path(bag).exists():
        return None
    fig = swarm_figure(scenario, Path(bag), outcome)
    path = RunPaths(Path(run_dir)).report
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=DPI)
    return path


def arena(scenario) -> World:
    """The static obstacles of the swarm's world (the robots are not static)."""
    from descriptions.swarm_world import swarm_model

    world = World()
    add_obstacles(world, swarm_model(scenario.world, scenario.robots))
    return world


def swarm_figure(scenario, bag: Path, outcome):
    """The arena from above with every robot's driven path in its own colour, its start
    (square), goal (star, tolerance circle) and where it ended (dot)."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    layout = scenario.robots
    topics = tuple(namespaced(layout.namespace_of(r), "/odom") for r in layout.names)
    data = read_bag(Path(bag), topics)
    world = arena(scenario)
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
