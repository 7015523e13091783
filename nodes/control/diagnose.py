"""Why the planner finds no way from start to goal, in words that name the obstacles.

Either the start or the goal lies inside the inflated zone of an obstacle (closer to it
than the plan may pass, with no free cell near), or no passage wide enough for the robot
joins the region reachable from the start to the region reachable from the goal: then the
obstacles whose inflated zones border both regions are the ones that close the way.
"""

from __future__ import annotations

import numpy as np

from nodes.control.grid import NEIGHBOURS, reachable

SHOWN = 8  # obstacles named at most; the rest are counted
SCAN = "points the scan saw (marked on the map by a recovery)"


def connected(planner, start: tuple[float, float], goal: tuple[float, float]) -> bool:
    """Whether the planner's most permissive costmap joins start and goal (no A* needed)."""
    cost = planner.narrow_cost
    s = planner.free_near(cost, planner.grid.cell(*start))
    g = planner.free_near(cost, planner.grid.cell(*goal))
    return s is not None and g is not None and planner.joined(True, s, g)


def explain_no_path(planner, start: tuple[float, float], goal: tuple[float, float]) -> str:
    """One sentence: why no plan joins start and goal, naming the obstacles in the way."""
    p = planner.p
    cost = planner.narrow_cost
    clear = planner.narrow_distance
    rule = (f"the plan keeps {clear:.2f} m from obstacles: robot_radius {p.robot_radius:g} m "
            f"+ safety_margin {p.safety_margin:g} m")
    cells = {}
    for what, (x, y) in (("start", start), ("goal", goal)):
        cell = planner.grid.cell(x, y)
        cells[what] = planner.free_near(cost, cell)
        if cells[what] is None:
            names = zones_at(planner, x, y, clear)
            return (f"no path: the {what} ({x:.2f}, {y:.2f}) is inside the inflated zone of "
                    f"{listing(names)} ({rule}), with no free cell within 0.6 m.")
    passable = np.isfinite(cost)
    near_start = reachable(passable, cells["start"])
    if near_start[cells["goal"]]:
        return "no path found (the costmap joins start and goal; this is a planner bug)."
    near_goal = reachable(passable, cells["goal"])
    own_start = blockers(planner, border(near_start, passable))
    own_goal = blockers(planner, border(near_goal, passable))
    closing = [n for n in own_start if n in own_goal]
    if not closing:
        closing = own_start if near_start.sum() < near_goal.sum() else own_goal
    return (f"no path from ({start[0]:.2f}, {start[1]:.2f}) to ({goal[0]:.2f}, {goal[1]:.2f}): "
            f"no passage wider than the robot ({2 * clear:.2f} m; {rule}) leads from the "
            f"start's side to the goal's; closing the way: {listing(closing)}.")


def border(region: np.ndarray, passable: np.ndarray) -> np.ndarray:
    """(n, 2) indices of the blocked cells next to ``region`` (where it ends)."""
    grown = region.copy()
    nx, ny = region.shape
    for di, dj, _ in NEIGHBOURS:
        src = region[max(-di, 0):nx - max(di, 0), max(-dj, 0):ny - max(dj, 0)]
        grown[max(di, 0):nx - max(-di, 0), max(dj, 0):ny - max(-dj, 0)] |= src
    return np.argwhere(grown & ~passable)


def blockers(planner, cells: np.ndarray) -> list[str]:
    """The obstacles nearest to ``cells`` (grid indices): names in the world's order, with
    the scan's marked points last when some cell is blocked only because of them."""
    if len(cells) == 0:
        return []
    grid = planner.grid
    xs = grid.origin[0] + (cells[:, 0] + 0.5) * grid.res
    ys = grid.origin[1] + (cells[:, 1] + 0.5) * grid.res
    dist = np.array([o.distances(xs, ys) for o in grid.obstacles])
    nearest = dist.argmin(axis=0)
    marked = planner.static_dist[cells[:, 0], cells[:, 1]] >= planner.narrow_distance
    names = [f"'{grid.obstacles[k].name}'" for k in sorted(set(nearest[~marked].tolist()))]
    return names + ([SCAN] if marked.any() else [])


def zones_at(planner, x: float, y: float, clear: float) -> list[str]:
    """The obstacles (and scan marks) whose inflated zone of ``clear`` covers (x, y)."""
    names = [f"'{o.name}'" for o in planner.grid.obstacles if o.distance(x, y) < clear]
    if mark_distances(planner, np.array([x]), np.array([y]))[0] < clear:
        names.append(SCAN)
    return names


def mark_distances(planner, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Distance from each point to the nearest scan point marked on the map (inf: none)."""
    marks = np.argwhere(planner.marked)
    if len(marks) == 0:
        return np.full(len(xs), np.inf)
    grid = planner.grid
    mx = grid.origin[0] + (marks[:, 0] + 0.5) * grid.res
    my = grid.origin[1] + (marks[:, 1] + 0.5) * grid.res
    return np.hypot(xs[:, None] - mx[None, :], ys[:, None] - my[None, :]).min(axis=1)


def listing(names: list[str]) -> str:
    """"obstacles 'a', 'b', 'c'" (the first SHOWN, then a count)."""
    if not names:
        return "nothing but the edge of the map"
    text = ", ".join(names[:SHOWN])
    if len(names) > SHOWN:
        text += f" and {len(names) - SHOWN} more"
    if names == [SCAN]:
        return text
    return ("obstacle " if len(names) == 1 else "obstacles ") + text
