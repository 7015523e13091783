"""The report picture of a run with a joint goal (an arm): each goal joint's position over
time against its goal, and the largest error to the goal against the tolerance."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

JOINT_STATES = "/joint_states"


def joint_goal_of(scenario):
    """The scenario's joint goal, or None."""
    return getattr(getattr(scenario, "model", None), "joint_goal", None)


def joint_series(messages: list[tuple[int, object]], joints: list[str]
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(times in s, positions: one column per joint, NaN where a message lacks it)."""
    t = np.array([stamp / 1e9 for stamp, _ in messages])
    q = np.full((len(messages), len(joints)), np.nan)
    for row, (_, msg) in enumerate(messages):
        position = dict(zip(msg.name, msg.position, strict=False))
        q[row] = [position.get(j, np.nan) for j in joints]
    return t, q


def joint_figure(scenario, data, outcome, title: str) -> Figure:
    """Joint positions and their goals on the left, the largest error on the right."""
    goal = joint_goal_of(scenario)
    joints = list(goal.positions)
    target = np.array([goal.positions[j] for j in joints])
    t, q = joint_series(data.messages.get(JOINT_STATES, []), joints)
    fig = Figure(figsize=(15, 6.5))
    grid = fig.add_gridspec(1, 2, left=0.06, right=0.98, top=0.86, bottom=0.1, wspace=0.2)
    ax_q, ax_e = fig.add_subplot(grid[0]), fig.add_subplot(grid[1])
    for i, name in enumerate(joints):
        colour = f"C{i % 10}"
        ax_q.plot(t, q[:, i], color=colour, lw=1.3, label=name)
        ax_q.axhline(target[i], color=colour, ls="--", lw=0.8)
    ax_q.set_xlabel("sim time [s]")
    ax_q.set_ylabel("position [rad] (dashed: goal)")
    ax_q.grid(True, alpha=0.25)
    ax_q.legend(loc="best", fontsize=8)
    if len(t):
        ax_e.plot(t, np.nanmax(np.abs(q - target), axis=1), color="black", lw=1.4,
                  label="largest joint error to the goal")
    ax_e.axhline(goal.tolerance, color="black", ls="--", lw=0.8, label="tolerance")
    ax_e.set_yscale("log")
    ax_e.set_xlabel("sim time [s]")
    ax_e.set_ylabel("error [rad]")
    ax_e.grid(True, alpha=0.25)
    ax_e.legend(loc="best", fontsize=8)
    fig.suptitle(title, fontsize=13)
    end = f", final largest error {np.nanmax(np.abs(q[-1] - target)):.4f} rad" if len(t) else ""
    fig.text(0.5, 0.915, f"{len(joints)} joints, goal tolerance {goal.tolerance} rad{end}",
             ha="center", fontsize=10, color="#444444")
    return fig
