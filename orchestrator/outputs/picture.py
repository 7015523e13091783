"""report.png: a picture of the run for someone who never saw it.

The picture is drawn from the bag alone (plus the MJCF world for the map), so it shows what
was recorded, not what a node believed. Runs with ``/odom`` get the navigation picture:

* left, the map seen from above: static obstacles of the world, the first and the last
  ``/plan``, the driven trajectory coloured by speed, start, goal with its tolerance circle,
  and the lidar returns of a few scans placed in the world with the odometry pose of the
  scan's tick (and the laser site's offset on the robot, read from the MJCF);
* right, over sim time: forward speed and turn rate (odometry and the ``/cmd_vel``
  commands), distance to the goal and the nearest lidar return.

A scenario with one robot in a ``robots:`` section gets the same picture from its robot's
topics (``orchestrator.outputs.lone_robot``). Runs without ``/odom`` (protocol tests, custom
nodes) get the messages received per topic over sim time. Figures are built on the Agg
canvas directly: no pyplot, no display, no global matplotlib state touched in the caller's
process.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon

from orchestrator.outputs.arm_picture import JOINT_STATES, joint_figure, joint_goal_of
from orchestrator.outputs.lone_robot import lone_robot, robot_goal, topics_of
from plan.poses import yaw_of
from plan.run_paths import RunPaths

if TYPE_CHECKING:
    from plan.scenario import Scenario

NAV_TOPICS = ("/odom", "/plan", "/scan", "/cmd_vel")
SNAPSHOTS = 4
SNAPSHOT_COLOURS = ("#d62728", "#9467bd", "#ff7f0e", "#17becf", "#e377c2", "#8c564b")
OBSTACLE_COLOUR = "#8c6d4f"
DPI = 110


@dataclass
class BagData:
    """What the picture needs from a bag: message counts, log times, a few topics decoded.

    Log times are read for every topic only when the bag has no ``/odom``.
    """

    counts: dict[str, int] = field(default_factory=dict)
    stamps: dict[str, np.ndarray] = field(default_factory=dict)
    messages: dict[str, list[tuple[int, object]]] = field(default_factory=dict)


@dataclass
class Track:
    """The odometry as arrays over sim time: pose in the odom frame, body-frame twist."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    v: np.ndarray
    w: np.ndarray
    ns: np.ndarray

    def pose_at(self, stamp_ns: int) -> tuple[float, float, float]:
        """The latest odometry pose at or before ``stamp_ns`` (x, y, yaw)."""
        i = max(int(np.searchsorted(self.ns, stamp_ns, side="right")) - 1, 0)
        return float(self.x[i]), float(self.y[i]), float(self.yaw[i])


def write_report_png(scenario: Scenario, run_dir: Path, bag: Path | None, outcome=None
                     ) -> Path | None:
    """Draw the run from its bag into ``<run dir>/report.png``; None when there is nothing.

    ``outcome`` (a RunOutcome) adds the status, digest and collisions to the title.
    """
    if bag is None or not Path(bag).exists():
        return None
    fig = report_figure(scenario, Path(bag), outcome)
    if fig is None:
        return None
    path = RunPaths(Path(run_dir)).report
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=DPI)
    return path


def report_figure(scenario: Scenario, bag: Path, outcome=None) -> Figure | None:
    """The picture of a run (one robot, an arm or neither) from its bag; None when the bag
    is empty."""
    arm = joint_goal_of(scenario) is not None
    topics = topics_of(scenario, NAV_TOPICS)  # nav's name -> the run's
    data = read_bag(bag, tuple(topics.values()) + ((JOINT_STATES,) if arm else ()),
                    odom=topics["/odom"])
    if not any(data.counts.values()):
        return None
    for name, topic in topics.items():  # the robot's topics, under nav's names
        if topic != name and topic in data.messages:
            data.messages[name] = data.messages.pop(topic)
    if arm and data.messages.get(JOINT_STATES):
        return joint_figure(scenario, data, outcome, title(scenario, outcome))
    if data.messages.get("/odom"):
        return nav_figure(scenario, data, outcome)
    return counts_figure(scenario, data, outcome)


def read_bag(bag: Path, decode: tuple[str, ...], odom: str = "/odom") -> BagData:
    """Log times of every topic, and the messages of the ``decode`` topics, from a bag
    (only those when it has odometry on ``odom``)."""
    from orchestrator.outputs.bag import BagReader

    data = BagData()
    with BagReader(bag) as reader:
        data.counts = reader.counts
        stamps: dict[str, list[int]] = {topic: [] for topic in data.counts}
        # the nav picture: skip images and the rest, count them
        chosen = [t for t in decode if t in data.counts] if data.counts.get(odom) else None
        last: dict[str, tuple[bytes, object]] = {}
        for topic, stamp, raw in reader.raw(chosen):
            stamps[topic].append(stamp)
            if topic in decode:
                msg = _decode(reader, topic, raw, last)
                data.messages.setdefault(topic, []).append((stamp, msg))
    data.stamps = {topic: np.asarray(s, dtype=np.int64) for topic, s in stamps.items()}
    return data


def _decode(reader, topic: str, raw: bytes, last: dict[str, tuple[bytes, object]]):
    """Deserialise a message, reusing the previous one of its topic when only the header
    stamp changed (a plan republished every control step costs one decode, not hundreds).

    Bytes 4-12 of a CDR message with a header are its stamp (after the encapsulation).
    """
    prev = last.get(topic)
    if prev is not None and prev[0] == raw[12:]:
        return prev[1]
    msg = reader.deserialize(raw, topic)
    if hasattr(msg, "header"):  # a message without one differs in its first bytes too
        last[topic] = (bytes(raw[12:]), msg)
    return msg


def odom_track(messages: list[tuple[int, object]]) -> Track:
    """The odometry messages as a Track."""
    ns = np.array([s for s, _ in messages], dtype=np.int64)
    poses = [m.pose.pose for _, m in messages]
    twists = [m.twist.twist for _, m in messages]
    return Track(t=ns / 1e9, ns=ns,
                 x=np.array([p.position.x for p in poses]),
                 y=np.array([p.position.y for p in poses]),
                 yaw=np.array([yaw_of(p.orientation) for p in poses]),
                 v=np.array([t.linear.x for t in twists]),
                 w=np.array([t.angular.z for t in twists]))


# --- the world ---------------------------------------------------------------------------


@dataclass
class World:
    """The map from above: obstacle outlines and where the laser sits on the robot."""

    polygons: list[np.ndarray] = field(default_factory=list)
    circles: list[tuple[float, float, float]] = field(default_factory=list)
    laser: tuple[float, float, float] = (0.0, 0.0, 0.0)
    spawned: list[tuple[str, np.ndarray]] = field(default_factory=list)  # (label, outline)


def load_world(path: Path | None, laser_frame: str = "laser") -> World:
    """Static obstacles of a world (top-down) and the laser site's offset on the robot.

    The obstacles are ``plan.obstacles``'s (the planner's), drawn when they sit in a
    visible geom group 0-2 (robot geoms live in group 3).
    """
    world = World()
    if path is None or not Path(path).exists():
        return world
    from descriptions.world_geometry import site_offset
    from descriptions.worldfile import load_world_model

    model = load_world_model(Path(path))
    add_obstacles(world, model)
    world.laser = site_offset(model, laser_frame)
    return world


def robots_world(scenario: Scenario, laser_frame: str) -> World:
    """The static obstacles of a ``robots:`` scenario's arena (the robots are not static)
    and where its robot's laser (``laser_frame``, a site of the robot's) sits on it."""
    from descriptions.swarm_world import swarm_model
    from descriptions.world_geometry import site_offset
    from plan.robots import frame_prefix

    world = World()
    layout = scenario.robots
    model = swarm_model(scenario.world, layout)
    add_obstacles(world, model)
    robot = layout.robots[0].name  # the frame in its namespace, the site under its prefix
    site = f"{robot}/{laser_frame.removeprefix(frame_prefix(layout.namespace_of(robot)))}"
    world.laser = site_offset(model, site)
    return world


def add_obstacles(world: World, model) -> None:
    """Add a compiled world's visible static obstacles to the picture's ``world``."""
    from descriptions.world_geometry import static_obstacles

    for o in static_obstacles(model):
        if not o.visible:
            continue
        if o.is_circle:
            world.circles.append((o.centre[0], o.centre[1], o.radius))
        else:
            world.polygons.append(o.polygon)


def add_spawned(world: World, events) -> None:
    """The outlines of the objects a scenario's ``events:`` spawn (a mesh as a small disc),
    each labelled with its name and when it came (and went)."""
    gone = {}
    for event in events:
        if event.delete is not None:
            gone.setdefault(event.delete, []).append(event.at)
    for event in events:
        obj = event.spawn
        if obj is None:
            continue
        p = obj.pose
        if obj.shape == "box":
            hx, hy = obj.size[0] / 2, obj.size[1] / 2
            c, s = math.cos(p.yaw), math.sin(p.yaw)
            outline = np.array([[p.x + c * x - s * y, p.y + s * x + c * y]
                                for x, y in ((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy))])
        else:
            r = obj.footprint_radius or 0.1
            a = np.linspace(0, 2 * math.pi, 24, endpoint=False)
            outline = np.column_stack([p.x + r * np.cos(a), p.y + r * np.sin(a)])
        until = [t for t in gone.get(obj.name, []) if t > event.at]
        when = f"{event.at / 1e9:g}-{min(until) / 1e9:g} s" if until else f"{event.at / 1e9:g} s"
        world.spawned.append((f"{obj.name} ({when})", outline))


def scan_points(scan, pose: tuple[float, float, float],
                laser: tuple[float, float, float]) -> np.ndarray:
    """The finite returns of a LaserScan as world points (N x 2), from the robot's pose."""
    ranges = np.asarray(scan.ranges, dtype=float)
    angles = scan.angle_min + scan.angle_increment * np.arange(len(ranges))
    ok = np.isfinite(ranges) & (ranges >= scan.range_min) & (ranges <= scan.range_max)
    x, y, yaw = pose
    lx = x + laser[0] * math.cos(yaw) - laser[1] * math.sin(yaw)
    ly = y + laser[0] * math.sin(yaw) + laser[1] * math.cos(yaw)
    beam = yaw + laser[2] + angles[ok]
    return np.column_stack([lx + ranges[ok] * np.cos(beam), ly + ranges[ok] * np.sin(beam)])


# --- the navigation picture --------------------------------------------------------------


def nav_figure(scenario: Scenario, data: BagData, outcome) -> Figure:
    """Map on the left, speeds, turn rate and distances over time on the right."""
    track = odom_track(data.messages["/odom"])
    scans = data.messages.get("/scan", [])
    laser_frame = scans[0][1].header.frame_id if scans else "laser"
    world = (robots_world(scenario, laser_frame) if lone_robot(scenario)
             else load_world(getattr(scenario, "world", None), laser_frame or "laser"))
    add_spawned(world, getattr(getattr(scenario, "model", None), "events", None) or [])
    snaps = snapshot_scans(scans)
    fig = Figure(figsize=(15, 9.5))
    left = fig.add_gridspec(1, 1, left=0.05, right=0.5, top=0.89, bottom=0.2)
    right = fig.add_gridspec(3, 1, left=0.6, right=0.98, top=0.89, bottom=0.07, hspace=0.12)
    ax_map = fig.add_subplot(left[0])
    draw_map(ax_map, fig, scenario, world, track, data, snaps)
    axes = [fig.add_subplot(right[i]) for i in range(3)]
    for ax in axes[1:]:
        ax.sharex(axes[0])
    draw_speed(axes[0], track, data.messages.get("/cmd_vel", []))
    draw_turn(axes[1], track, data.messages.get("/cmd_vel", []))
    draw_distances(axes[2], scenario, track, scans)
    goal_t = goal_time(scenario, track, outcome)
    for ax in axes:
        mark_instants(ax, snaps, goal_t)
    for ax in axes[:2]:
        ax.tick_params(labelbottom=False)
    axes[2].set_xlabel("sim time [s]")
    fig.suptitle(title(scenario, outcome, track), fontsize=13)
    fig.text(0.5, 0.925, subtitle(scenario, track, data, outcome), ha="center", fontsize=10,
             color="#444444")
    notes = notes_text(outcome)
    if notes:
        fig.text(0.01, 0.005, notes, ha="left", va="bottom", fontsize=8, color="#8b0000")
    twin = (getattr(outcome, "live", None) or {}).get("twin")
    if twin:
        from orchestrator.outputs.twin_rows import twin_line

        fig.text(0.01, 0.06 if notes else 0.005, twin_line(twin), ha="left", va="bottom",
                 fontsize=8, color="#00008b")
    return fig


def notes_text(outcome, shown: int = 2, width: int = 125) -> str:
    """The first notes of the run's nodes, wrapped to the map's half of the picture (why
    the controller stood still, ...)."""
    import textwrap

    notes = list(getattr(outcome, "notes", None) or [])
    lines = [textwrap.fill(f"note: {n.node} at {n.time_ns / 1e9:.2f} s: {n.text}", width)
             for n in notes[:shown]]
    if len(notes) > shown:
        lines.append(f"... {len(notes) - shown} more notes in manifest.json")
    return "\n".join(lines)


def snapshot_scans(scans: list[tuple[int, object]]) -> list[tuple[int, object, str]]:
    """A few scans spread over the run (first, last and evenly between), with a colour."""
    if not scans:
        return []
    n = min(SNAPSHOTS, len(scans))
    picks = sorted({round(i * (len(scans) - 1) / max(n - 1, 1)) for i in range(n)})
    return [(scans[i][0], scans[i][1], SNAPSHOT_COLOURS[j % len(SNAPSHOT_COLOURS)])
            for j, i in enumerate(picks)]


def draw_map(ax, fig, scenario: Scenario, world: World, track: Track, data: BagData, snaps) -> None:
    """Obstacles, plans, the driven trajectory, lidar snapshots, start and goal."""
    draw_obstacles(ax, world)
    draw_plans(ax, data.messages.get("/plan", []))
    for stamp, scan, colour in snaps:
        pose = track.pose_at(stamp)
        pts = scan_points(scan, pose, world.laser)
        ax.scatter(pts[:, 0], pts[:, 1], s=4, color=colour, zorder=4,
                   label=f"lidar returns at {stamp / 1e9:.1f} s")
        draw_robot(ax, pose, colour)
    draw_trajectory(ax, fig, track)
    draw_start_goal(ax, scenario, track)
    ax.set_aspect("equal")
    xlim, ylim = map_limits(world, track, scenario)
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, alpha=0.25)
    legend = ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.07), ncol=3, fontsize=8,
                       frameon=False)
    for handle in legend.legend_handles:
        if hasattr(handle, "set_sizes"):
            handle.set_sizes([25])


def draw_obstacles(ax, world: World) -> None:
    """Static obstacles as filled outlines."""
    style = {"facecolor": OBSTACLE_COLOUR, "edgecolor": "#4d3b2a", "alpha": 0.85, "zorder": 1}
    for poly in world.polygons:
        ax.add_patch(Polygon(poly, closed=True, **style))
    for x, y, r in world.circles:
        ax.add_patch(Circle((x, y), r, **style))
    if world.polygons or world.circles:
        ax.add_patch(Polygon(np.zeros((3, 2)), label="obstacles (MJCF)", **style))
    spawned = {"facecolor": "#9ab3d5", "edgecolor": "#2f4f7f", "hatch": "//", "alpha": 0.8,
               "zorder": 1}
    for label, outline in world.spawned:
        ax.add_patch(Polygon(outline, closed=True, **spawned))
        ax.annotate(label, outline.mean(axis=0), fontsize=7, ha="center", va="bottom",
                    xytext=(0, 6), textcoords="offset points", zorder=6)
    if world.spawned:
        ax.add_patch(Polygon(np.zeros((3, 2)), label="spawned (events:)", **spawned))


def draw_plans(ax, plans: list[tuple[int, object]]) -> None:
    """The first plan and, when it differs, the last one."""
    if not plans:
        return
    first, last = plans[0], plans[-1]
    xy_first, xy_last = plan_xy(first[1]), plan_xy(last[1])
    changes = sum(1 for (_, a), (_, b) in zip(plans, plans[1:], strict=False)
                  if not np.array_equal(plan_xy(a), plan_xy(b)))
    same = np.array_equal(xy_first, xy_last)
    label = (f"plan ({len(plans)} /plan messages, never changed)" if same
             else f"first plan ({first[0] / 1e9:.1f} s)")
    if len(xy_first):
        ax.plot(xy_first[:, 0], xy_first[:, 1], "--", color="#1f77b4", lw=1.6, zorder=2,
                label=label)
    if len(xy_last) and not same:
        ax.plot(xy_last[:, 0], xy_last[:, 1], ":", color="#7f7f00", lw=2, zorder=2,
                label=f"last plan ({last[0] / 1e9:.1f} s; changed {changes}x in all)")


def plan_xy(path) -> np.ndarray:
    """A nav_msgs Path as an N x 2 array."""
    return np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses]).reshape(-1, 2)


def draw_trajectory(ax, fig, track: Track) -> None:
    """The driven path, coloured by forward speed, with a colour bar."""
    pts = np.column_stack([track.x, track.y])
    if len(pts) < 2:
        return
    segments = np.stack([pts[:-1], pts[1:]], axis=1)
    speed = np.abs(track.v[1:])
    lc = LineCollection(segments, cmap="viridis", linewidths=3, zorder=3,
                        label="driven (odometry; colour = speed)")
    lc.set_array(speed)
    lc.set_clim(0, max(float(speed.max()), 1e-3))
    ax.add_collection(lc)
    bar = fig.colorbar(lc, ax=ax, fraction=0.04, pad=0.02)
    bar.set_label("speed [m/s]")


def draw_robot(ax, pose: tuple[float, float, float], colour: str) -> None:
    """The robot at a pose: a dot with a heading tick."""
    x, y, yaw = pose
    ax.plot([x, x + 0.3 * math.cos(yaw)], [y, y + 0.3 * math.sin(yaw)], color=colour, lw=2,
            zorder=6)
    ax.plot(x, y, "o", color=colour, markeredgecolor="black", ms=7, zorder=6)


def draw_start_goal(ax, scenario: Scenario, track: Track) -> None:
    """Start (first odometry pose) and the goal with its tolerance circle and heading."""
    ax.plot(track.x[0], track.y[0], "s", color="white", markeredgecolor="black", ms=10,
            zorder=7, label=f"start ({track.x[0]:.2f}, {track.y[0]:.2f})")
    ax.plot(track.x[-1], track.y[-1], "o", color="black", ms=6, zorder=7,
            label=f"end ({track.x[-1]:.2f}, {track.y[-1]:.2f}) at {track.t[-1]:.1f} s")
    goal = scenario_goal(scenario)
    if goal is None:
        return
    ax.plot(goal.x, goal.y, "*", color="gold", markeredgecolor="black", ms=16, zorder=7,
            label=f"goal ({goal.x:.2f}, {goal.y:.2f}), tolerance {goal.position_tolerance} m")
    ax.add_patch(Circle((goal.x, goal.y), goal.position_tolerance, fill=False, ls="--",
                        edgecolor="black", zorder=7))
    ax.annotate("", xy=(goal.x + 0.45 * math.cos(goal.yaw), goal.y + 0.45 * math.sin(goal.yaw)),
                xytext=(goal.x, goal.y), zorder=7,
                arrowprops={"arrowstyle": "->", "color": "black", "lw": 1.5})


def scenario_goal(scenario: Scenario):
    """The scenario's goal (its lone robot's in a ``robots:`` section), or None."""
    model = getattr(scenario, "model", None)
    return getattr(model, "goal", None) or robot_goal(scenario)


def map_limits(world: World, track: Track, scenario: Scenario):
    """x and y limits that hold the obstacles, the trajectory and the goal, with a margin."""
    xs, ys = [track.x.min(), track.x.max()], [track.y.min(), track.y.max()]
    for poly in world.polygons:
        xs += [poly[:, 0].min(), poly[:, 0].max()]
        ys += [poly[:, 1].min(), poly[:, 1].max()]
    for x, y, r in world.circles:
        xs += [x - r, x + r]
        ys += [y - r, y + r]
    goal = scenario_goal(scenario)
    if goal is not None:
        xs += [goal.x - 0.5, goal.x + 0.5]
        ys += [goal.y - 0.5, goal.y + 0.5]
    m = 0.3
    return (min(xs) - m, max(xs) + m), (min(ys) - m, max(ys) + m)


def cmd_series(cmds: list[tuple[int, object]], attr: str) -> tuple[np.ndarray, np.ndarray]:
    """Times and one component (linear.x or angular.z) of the /cmd_vel commands."""
    t = np.array([s / 1e9 for s, _ in cmds])
    part, axis = attr.split(".")
    return t, np.array([getattr(getattr(m, part), axis) for _, m in cmds])


def draw_speed(ax, track: Track, cmds) -> None:
    """Forward speed: odometry, and the commands held until the next one."""
    ax.plot(track.t, track.v, color="#1f77b4", lw=1.4, label="odometry (body x)")
    if cmds:
        t, v = cmd_series(cmds, "linear.x")
        ax.step(t, v, where="post", color="#2ca02c", lw=1, alpha=0.9, label="/cmd_vel linear.x")
    ax.set_ylabel("speed [m/s]")
    ax.axhline(0, color="grey", lw=0.6)
    ax.grid(True, alpha=0.25)
    ax.legend(loc="best", fontsize=8)


def draw_turn(ax, track: Track, cmds) -> None:
    """Turn rate: odometry, and the commands."""
    ax.plot(track.t, track.w, color="#1f77b4", lw=1.4, label="odometry (yaw rate)")
    if cmds:
        t, w = cmd_series(cmds, "angular.z")
        ax.step(t, w, where="post", color="#2ca02c", lw=1, alpha=0.9,
                label="/cmd_vel angular.z")
    ax.set_ylabel("turn rate [rad/s]")
    ax.axhline(0, color="grey", lw=0.6)
    ax.grid(True, alpha=0.25)
    ax.legend(loc="best", fontsize=8)


def draw_distances(ax, scenario: Scenario, track: Track, scans) -> None:
    """Distance to the goal and the nearest lidar return, over time."""
    goal = scenario_goal(scenario)
    if goal is not None:
        ax.plot(track.t, np.hypot(track.x - goal.x, track.y - goal.y), color="black", lw=1.4,
                label="distance to goal")
        ax.axhline(goal.position_tolerance, color="black", ls="--", lw=0.8,
                   label="goal tolerance")
    if scans:
        t = np.array([s / 1e9 for s, _ in scans])
        nearest = np.array([nearest_return(m) for _, m in scans])
        ax.plot(t, nearest, color="#8c564b", lw=1.2, label="nearest lidar return")
    ax.set_ylabel("distance [m]")
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.25)
    if ax.get_legend_handles_labels()[0]:  # nothing drawn without a goal or a lidar (an arm)
        ax.legend(loc="best", fontsize=8)


def nearest_return(scan) -> float:
    """The shortest valid range of a scan (NaN when nothing was hit)."""
    r = np.asarray(scan.ranges, dtype=float)
    r = r[np.isfinite(r) & (r >= scan.range_min) & (r <= scan.range_max)]
    return float(r.min()) if len(r) else math.nan


def goal_time(scenario: Scenario, track: Track, outcome) -> float | None:
    """When the goal was reached: the control node's time_to_goal, else by odometry."""
    metrics = outcome_metrics(outcome)
    if metrics.get("goal_reached", 0) >= 1 and "time_to_goal" in metrics:
        return float(metrics["time_to_goal"])
    goal = scenario_goal(scenario)
    if goal is None or outcome is not None:
        return None
    inside = np.flatnonzero(np.hypot(track.x - goal.x, track.y - goal.y)
                            <= goal.position_tolerance)
    return float(track.t[inside[0]]) if len(inside) else None


def mark_instants(ax, snaps, goal_t: float | None) -> None:
    """Vertical lines at the lidar snapshots (their colours) and when the goal was reached."""
    for stamp, _, colour in snaps:
        ax.axvline(stamp / 1e9, color=colour, lw=0.9, alpha=0.6)
    if goal_t is not None:
        ax.axvline(goal_t, color="gold", lw=2.5, alpha=0.9)
        ax.annotate("goal reached", (goal_t, 1), xycoords=("data", "axes fraction"),
                    xytext=(-4, -12), textcoords="offset points", ha="right", fontsize=8)


# --- titles ------------------------------------------------------------------------------


def outcome_metrics(outcome) -> dict[str, float]:
    """Every node's metrics, flattened (empty without an outcome)."""
    result = getattr(outcome, "result", None)
    if result is None:
        return {}
    return {k: v for m in result.metrics.values() for k, v in m.items()}


def title(scenario: Scenario, outcome, track: Track | None = None) -> str:
    """'nav: SUCCESS, 0 collisions, digest 4cb73072' (what is known)."""
    parts = [f"{getattr(scenario, 'name', 'run')}:"]
    if outcome is not None:
        parts.append(outcome.status.upper().replace("_", " "))
        if track is not None:
            parts.append(f"- {outcome.collisions} collision"
                         f"{'' if outcome.collisions == 1 else 's'}")
        if outcome.digest:
            parts.append(f"- digest {outcome.digest[:12]}")
        if outcome.error:
            parts.append(f"- {outcome.error.splitlines()[0][:80]}")
    else:
        parts.append("run report (outcome: see manifest.json)")
    return " ".join(parts)


def subtitle(scenario: Scenario, track: Track, data: BagData, outcome) -> str:
    """Sim time, distance driven, final distance to the goal, messages recorded."""
    driven = float(np.hypot(np.diff(track.x), np.diff(track.y)).sum())
    text = [f"{track.t[-1]:.2f} s simulated", f"{driven:.2f} m driven",
            f"top speed {np.abs(track.v).max():.2f} m/s"]
    goal = scenario_goal(scenario)
    if goal is not None:
        left = math.hypot(track.x[-1] - goal.x, track.y[-1] - goal.y)
        text.append(f"ends {left:.2f} m from the goal")
    metrics = outcome_metrics(outcome)
    if "min_clearance" in metrics:
        text.append(f"min clearance {metrics['min_clearance']:.2f} m")
    text.append(f"{sum(data.counts.values())} messages in the bag")
    return ",  ".join(text)


# --- the generic picture -----------------------------------------------------------------


def counts_figure(scenario: Scenario, data: BagData, outcome) -> Figure:
    """Messages recorded per topic: when each was published over sim time, and totals."""
    fig = Figure(figsize=(13, 6))
    grid = fig.add_gridspec(1, 2, width_ratios=(1.6, 1), wspace=0.35, left=0.06, right=0.97,
                            top=0.86, bottom=0.1)
    ax_t, ax_n = fig.add_subplot(grid[0]), fig.add_subplot(grid[1])
    topics = sorted(data.stamps)
    colours = [f"C{i % 10}" for i in range(len(topics))]
    ax_t.eventplot([data.stamps[t] / 1e9 for t in topics], colors=colours, linelengths=0.7,
                   linewidths=0.8)
    ax_t.set_yticks(range(len(topics)), topics)
    ax_t.invert_yaxis()
    ax_t.set_xlabel("sim time [s] (log time of each message)")
    ax_t.set_title("when each topic was published", fontsize=10)
    ax_t.grid(True, axis="x", alpha=0.25)
    counts = [len(data.stamps[t]) for t in topics]
    bars = ax_n.barh(topics, counts, color=colours)
    ax_n.bar_label(bars, padding=3, fontsize=8)
    ax_n.invert_yaxis()
    ax_n.set_xlabel("messages recorded")
    ax_n.set_xlim(0, max(counts + [1]) * 1.15)
    fig.suptitle(title(scenario, outcome), fontsize=13)
    last = max((int(s.max()) for s in data.stamps.values() if len(s)), default=0)
    fig.text(0.5, 0.915, f"no /odom in this run: messages per topic over {last / 1e9:.2f} s "
             f"of sim time, {sum(counts)} in all", ha="center", fontsize=10, color="#444444")
    return fig
