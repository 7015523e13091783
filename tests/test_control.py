"""Control node: map building, A*, scan handling, goal checking and its latched metrics."""

from __future__ import annotations

import array
import math

import mujoco
import numpy as np
import pytest
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

from nodes.contract import NodeConfig, Tick
from nodes.control.follow import arc_clearance, arc_clearances
from nodes.control.global_planner import Planner
from nodes.control.grid import (
    HEURISTIC_WEIGHT,
    NEIGHBOURS,
    astar,
    components,
    reachable,
    world_grid,
)
from nodes.control.node import ControlNode
from tests.worlds import write_world

WALL = '<geom name="wall" type="box" pos="0 0 0.5" size="0.1 1.5 0.5"/>'


def test_map_marks_static_obstacles_only(tmp_path):
    model = mujoco.MjModel.from_xml_path(str(write_world(tmp_path, WALL)))
    grid = world_grid(model, 0.05, (0.02, 0.6))
    assert grid.occ[grid.cell(0.0, 0.0)] and grid.occ[grid.cell(0.0, 1.4)]
    assert not grid.occ[grid.cell(0.0, 1.7)] and not grid.occ[grid.cell(0.3, 0.0)]


def test_astar_finds_a_path_around_an_obstacle():
    cost = np.ones((40, 40))
    cost[20, 0:35] = np.inf  # a wall with a gap at the top
    path = astar(cost, (5, 5), (35, 5))
    assert path is not None and path[0] == (5, 5) and path[-1] == (35, 5)
    assert all(math.isfinite(cost[c]) for c in path)
    assert any(j >= 35 for i, j in path if i == 20)
    for (a, b), (c, d) in zip(path, path[1:], strict=False):
        assert max(abs(a - c), abs(b - d)) == 1


def test_astar_reports_no_path():
    cost = np.ones((10, 10))
    cost[5, :] = np.inf
    assert astar(cost, (1, 1), (8, 8)) is None


def test_arc_clearance_stops_before_a_point_ahead():
    pts = np.array([[1.0, 0.0]])
    free = arc_clearance(pts, (0.0, 0.0, 0.0), 0.5, 0.0, 2.0, 0.3)
    assert 0.6 <= free <= 0.7
    assert arc_clearance(pts, (0.0, 0.0, 0.0), -0.5, 0.0, 2.0, 0.3) == 2.0
    assert arc_clearance(pts, (0.0, 0.0, math.pi / 2), 0.5, 0.0, 2.0, 0.3) == 2.0


def _one_arc(points, pose, v, w, horizon, radius):
    """arc_clearance as it was written for one arc (the reference for the batched one)."""
    if len(points) == 0 or v == 0:
        return horizon
    ds = 0.05
    s = np.arange(ds, horizon + 1e-9, ds)
    k = w / abs(v)
    th = pose[2] + k * s
    sign = math.copysign(1.0, v)
    if abs(k) < 1e-6:
        xs = pose[0] + sign * s * math.cos(pose[2])
        ys = pose[1] + sign * s * math.sin(pose[2])
    else:
        xs = pose[0] + sign * (np.sin(th) - math.sin(pose[2])) / k
        ys = pose[1] - sign * (np.cos(th) - math.cos(pose[2])) / k
    near = points[np.hypot(points[:, 0] - pose[0], points[:, 1] - pose[1]) < horizon + radius]
    if len(near) == 0:
        return horizon
    d2 = (xs[:, None] - near[None, :, 0]) ** 2 + (ys[:, None] - near[None, :, 1]) ** 2
    hit = np.flatnonzero(d2.min(axis=1) < radius * radius)
    return float(s[hit[0]] - ds) if hit.size else horizon


def test_a_fan_of_arcs_at_once_is_each_arc_alone_bit_for_bit():
    rng = np.random.default_rng(3)
    for _ in range(300):
        points = rng.uniform(-2, 2, (int(rng.integers(0, 120)), 2))
        pose = tuple(rng.uniform(-1, 1, 3).tolist())
        v = float(rng.choice([0.0, -0.1, 0.05, rng.uniform(-0.5, 0.5)]))
        horizon, radius = float(rng.choice([1.0, 0.2, rng.uniform(0.1, 2)])), 0.27
        ws = [v * k for k in np.linspace(-3, 3, 11).tolist() + [1e-7]]
        assert arc_clearances(points, pose, v, ws, horizon, radius) == [
            _one_arc(points, pose, v, w, horizon, radius) for w in ws]


def odom(x: float, y: float, yaw: float) -> Odometry:
    """Odometry at a planar pose."""
    msg = Odometry()
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return msg


def empty_scan(ranges=None) -> LaserScan:
    """A 360-beam scan, all +inf unless given."""
    scan = LaserScan()
    scan.angle_min, scan.angle_increment = -math.pi, 2 * math.pi / 360
    scan.range_min, scan.range_max = 0.12, 12.0
    scan.ranges = array.array("f", ranges if ranges is not None else [math.inf] * 360)
    return scan


def control(tmp_path, goal) -> ControlNode:
    """A reset control node in a world with one wall at x = 0."""
    node = ControlNode()
    node.reset(0, NodeConfig("control", ControlNode.Params(), 1_000_000, 100_000_000,
                             write_world(tmp_path, WALL), goal=goal))
    return node


def test_plan_goes_around_the_wall_and_heads_off(tmp_path):
    node = control(tmp_path, {"x": 2.0, "y": 0.0, "yaw": 0.0, "position_tolerance": 0.2,
                              "yaw_tolerance": 0.3})
    facing_away = odom(-2.0, 0.0, math.pi)
    out = node.step(Tick(0, 0), {"/odom": facing_away, "/scan": empty_scan()})
    plan = out["/plan"]
    assert plan.header.frame_id == "odom" and len(plan.poses) > 10
    ys = [p.pose.position.y for p in plan.poses]
    assert max(abs(y) for y in ys) > 1.5 + 0.3  # around an end of the wall, with clearance
    assert out["/cmd_vel"].angular.z != 0.0 and out["/cmd_vel"].linear.x == 0.0  # turn first


def test_goal_reached_latches_and_stops(tmp_path):
    node = control(tmp_path, {"x": 2.0, "y": 1.0, "yaw": 0.0, "position_tolerance": 0.2,
                              "yaw_tolerance": 0.3})
    inputs = {"/odom": odom(2.05, 1.0, 0.05), "/scan": empty_scan()}
    out = node.step(Tick(3, 300_000_000), inputs)
    assert out["/cmd_vel"].linear.x == 0.0 and out["/cmd_vel"].angular.z == 0.0
    assert node.metrics()["goal_reached"] == 1.0
    assert node.metrics()["time_to_goal"] == 0.3
    away = {"/odom": odom(0.0, -2.0, 2.0), "/scan": empty_scan()}
    out = node.step(Tick(4, 400_000_000), away)
    assert node.metrics()["goal_reached"] == 1.0 and out["/cmd_vel"].linear.x == 0.0
    assert node.metrics()["path_length"] > 3.0


def test_turns_to_the_goal_heading_before_reaching(tmp_path):
    node = control(tmp_path, {"x": 2.0, "y": 1.0, "yaw": 1.5, "position_tolerance": 0.2,
                              "yaw_tolerance": 0.3})
    out = node.step(Tick(0, 0), {"/odom": odom(2.0, 1.0, 0.0), "/scan": empty_scan()})
    assert out["/cmd_vel"].angular.z > 0 and out["/cmd_vel"].linear.x == 0.0
    assert node.metrics()["goal_reached"] == 0.0 and node.metrics()["time_to_goal"] == -1.0


def test_stops_short_of_an_unmapped_obstacle(tmp_path):
    node = control(tmp_path, {"x": -2.0, "y": 3.0, "yaw": 0.0, "position_tolerance": 0.2,
                              "yaw_tolerance": 3.0})
    ranges = [math.inf] * 360
    ranges[180] = 0.3  # straight ahead of the laser, not on the map
    out = node.step(Tick(0, 0), {"/odom": odom(-2.0, -1.0, math.pi / 2),
                                 "/scan": empty_scan(ranges)})
    assert out["/cmd_vel"].linear.x == 0.0
    assert math.isclose(node.metrics()["min_clearance"], 0.3, rel_tol=1e-6)


# -- the map is drawn at the obstacles' true size (issue 19) -------------------------------

PILLAR_ROW = "\n".join(  # pillars of r = 0.29 m, 1.2 m high, 0.9 m apart surface to surface
    f'<geom name="p{i}" type="cylinder" pos="0 {y:.2f} 0.6" size="0.29 0.6"/>'
    for i, y in enumerate(np.arange(-3.54, 4.0, 1.48)))
WALLS = ('<geom name="n" type="box" pos="0 3.9 0.3" size="4 0.05 0.3"/>'  # a closed room
         '<geom name="s" type="box" pos="0 -3.9 0.3" size="4 0.05 0.3"/>'
         '<geom name="e" type="box" pos="4 0 0.3" size="0.05 4 0.3"/>'
         '<geom name="w" type="box" pos="-4 0 0.3" size="0.05 4 0.3"/>')


def planner(world) -> Planner:
    model = mujoco.MjModel.from_xml_path(str(world))
    return Planner(model, ControlNode.Params())


def test_a_path_between_pillars_exists_at_their_true_radius(tmp_path):
    # a bounding sphere (sqrt(0.29^2 + 0.6^2) = 0.67 m) would close every gap of the row
    plan = planner(write_world(tmp_path, PILLAR_ROW + WALLS)).plan((-2.0, 0.74), (2.0, 0.74))
    assert plan is not None
    assert min(abs(x) for x, _ in plan.tolist()) < 0.1  # it crosses the row


@pytest.mark.parametrize(("geom", "inside", "outside"), [
    ('type="box" pos="0 0 0.3" size="0.5 0.2 0.3" euler="0 0 45"',
     [(0.3, 0.3), (-0.3, -0.3)], [(0.3, -0.3), (0.0, 0.45)]),
    ('type="cylinder" pos="0 0 0.3" size="0.4 0.3"', [(0.36, 0.0), (0.0, -0.36)],
     [(0.48, 0.0), (0.35, 0.35)]),
    ('type="capsule" pos="0 0 0.5" size="0.3 0.2"', [(0.26, 0.0)], [(0.38, 0.0)]),
    ('type="sphere" pos="0 0 0.3" size="0.35"', [(0.31, 0.0)], [(0.43, 0.0)]),
    ('type="cylinder" pos="0 0 0.2" size="0.2 0.6" euler="0 90 0"',  # lying: its hull
     [(0.55, 0.0), (-0.55, 0.15)], [(0.72, 0.0), (0.0, 0.3)]),
    ('type="ellipsoid" pos="0 0 0.3" size="0.5 0.2 0.3"', [(0.45, 0.0)], [(0.6, 0.0)]),
])
def test_each_geom_type_covers_its_own_footprint(tmp_path, geom, inside, outside):
    model = mujoco.MjModel.from_xml_path(str(write_world(tmp_path, f'<geom name="g" {geom}/>')))
    grid = world_grid(model, 0.05, (0.02, 0.6))
    for x, y in inside:
        assert grid.occ[grid.cell(x, y)], (geom, x, y)
    for x, y in outside:
        assert not grid.occ[grid.cell(x, y)], (geom, x, y)


def test_report_picture_draws_cylinders_as_circles(tmp_path):
    from orchestrator.outputs.picture import load_world

    world = load_world(write_world(tmp_path, PILLAR_ROW + WALLS))
    assert sorted(r for _, _, r in world.circles) == [0.29] * 6
    assert len(world.polygons) == 4


# -- a robot costs what it must (issue 41) ---------------------------------------------------


def test_planners_of_one_world_share_the_static_map_until_one_marks_points(tmp_path):
    model = mujoco.MjModel.from_xml_path(str(write_world(tmp_path, WALL)))
    a, b = Planner(model, ControlNode.Params()), Planner(model, ControlNode.Params())
    assert a.cost is b.cost and a.static_dist is b.static_dist
    assert a.plan((-2.0, 0.0), (2.0, 0.0)) is not None
    assert a.derived is b.derived and ("labels", False) in b.derived  # one flood fill for both
    a.mark(np.array([[-1.0, -3.0], [-1.0, -3.05]]))  # an unmapped thing: a's map only
    assert a.cost is not b.cost and np.isinf(a.cost[a.grid.cell(-1.0, -3.0)])
    assert np.isfinite(b.cost[b.grid.cell(-1.0, -3.0)])
    assert not b.static_dist.flags.writeable  # shared: nobody may write into it
    wider = Planner(model, ControlNode.Params(lethal_distance=0.4))
    assert wider.cost is not a.shared.cost  # other map parameters: a map of their own


def test_components_join_what_a_flood_fill_joins():
    passable = np.ones((30, 30), dtype=bool)
    passable[15, :] = False  # two halves
    passable[5, 5] = False
    labels = components(passable)
    assert labels[0, 0] == labels[14, 29] != labels[16, 0] == labels[29, 29] != 0
    assert labels[15, 3] == 0 and labels[5, 5] == 0
    assert (labels == labels[0, 0]).sum() == reachable(passable, (0, 0)).sum()


def test_astar_plans_within_the_heuristic_weight_of_the_cheapest():
    rng = np.random.default_rng(3)
    cost = 1.0 + rng.uniform(0.0, 3.0, (40, 40))
    cost[20, 5:40] = np.inf

    def length(path):
        return sum(math.hypot(a - c, b - d) * 0.5 * (cost[a, b] + cost[c, d])
                   for (a, b), (c, d) in zip(path, path[1:], strict=False))

    path = astar(cost, (2, 30), (38, 30))
    dijkstra = _cheapest(cost, (2, 30), (38, 30))
    assert dijkstra <= length(path) <= HEURISTIC_WEIGHT * dijkstra + 1e-9


def _cheapest(cost: np.ndarray, start, goal) -> float:
    """Dijkstra's cost of the cheapest 8-connected path (the reference for A*)."""
    import heapq

    best, heap = {start: 0.0}, [(0.0, start)]
    while heap:
        g, (i, j) = heapq.heappop(heap)
        if (i, j) == goal:
            return g
        if g > best[(i, j)]:
            continue
        for di, dj, step in NEIGHBOURS:
            a, b = i + di, j + dj
            if 0 <= a < cost.shape[0] and 0 <= b < cost.shape[1] and np.isfinite(cost[a, b]):
                ng = g + step * 0.5 * (cost[i, j] + cost[a, b])
                if ng < best.get((a, b), math.inf):
                    best[(a, b)] = ng
                    heapq.heappush(heap, (ng, (a, b)))
    return math.inf


@pytest.mark.parametrize(("centre", "turn"), [(200, -1.0), (160, 1.0)])
def test_steps_aside_from_an_unmapped_robot_without_replanning(tmp_path, centre, turn):
    node = ControlNode()
    node.reset(0, NodeConfig("control", ControlNode.Params(), 1_000_000, 100_000_000,
                             write_world(tmp_path, WALLS),
                             goal={"x": -2.0, "y": 3.0, "yaw": 0.0, "position_tolerance": 0.2,
                                   "yaw_tolerance": 3.0}))
    here = odom(-2.0, -2.0, math.pi / 2)
    out = node.step(Tick(0, 0), {"/odom": here, "/scan": empty_scan()})
    assert out["/cmd_vel"].linear.x > 0.2 and abs(out["/cmd_vel"].angular.z) < 0.2
    plan = node.path
    ranges = [math.inf] * 360
    for k in range(centre - 8, centre + 9):  # a robot-sized thing 0.5 m away, 20 degrees
        ranges[k] = 0.5  # to one side of straight ahead, not on the map
    out = node.step(Tick(1, 100_000_000), {"/odom": here, "/scan": empty_scan(ranges)})
    assert out["/cmd_vel"].linear.x > 0.2 and out["/cmd_vel"].angular.z * turn > 0.3  # away
    assert node.path is plan and node.recoveries == 0  # the plan is kept


def test_the_plan_built_into_slots_is_the_constructors_message():
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Path

    from nodes.control.global_planner import path_message
    from runtime.cdr.encode import encode

    path = np.random.default_rng(2).uniform(-5, 5, (40, 2))
    want = Path()
    want.header.frame_id = "r7/odom"
    yaws = [math.atan2(dy, dx) for dx, dy in np.diff(path, axis=0).tolist()] + [0.7]
    for (x, y), yaw in zip(path.tolist(), yaws, strict=True):
        ps = PoseStamped()
        ps.header.frame_id = "r7/odom"
        ps.pose.position.x, ps.pose.position.y = x, y
        ps.pose.orientation.z, ps.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        want.poses.append(ps)
    got = path_message(path, "r7/odom", 0.7)
    assert got == want and encode(got) == encode(want)
