"""Sensors node: lidar ranges, seeded noise, 3D lidar, depth image and camera intrinsics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Float64MultiArray

from nodes.contract import NodeConfig, Tick
from nodes.physics.node import PhysicsNode
from nodes.sensors.node import SensorsNode
from tests.worlds import write_world

TICK = 20_000_000
LASER_X = 0.08  # the laser site's x on base_link (scenarios/worlds/robot.xml)
CAMERA_X = -0.05 + 0.03  # pan_link x + camera x on tilt_link


def world_state(world, **start):
    """The physics node's /cosim/world_state at tick 0, through CDR like a transport."""
    physics = PhysicsNode()
    physics.reset(0, NodeConfig("physics", PhysicsNode.Params(start=start or None), TICK, TICK,
                                world))
    msg = physics.step(Tick(0, 0), {})["/cosim/world_state"]
    return deserialize_message(serialize_message(msg), Float64MultiArray)


def sensors(world, seed=0, warm_up=True, **params) -> SensorsNode:
    """A reset sensors node running the given sensors."""
    node = SensorsNode()
    node.reset(seed, NodeConfig("lidar", SensorsNode.Params(**params), TICK, 5 * TICK, world,
                                render_warm_up=warm_up))
    return node


def measure(node, state) -> dict:
    """One activation."""
    return node.step(Tick(0, 0), {"/cosim/world_state": state})


def ranges(scan) -> np.ndarray:
    """LaserScan ranges as a numpy array."""
    return np.frombuffer(scan.ranges, dtype=np.float32)


BOX = '<geom name="box" type="box" pos="{x} 0 0.5" size="0.1 0.5 0.5"/>'


def test_box_at_known_distance_gives_expected_range(tmp_path):
    world = write_world(tmp_path, BOX.format(x=2.1))  # near face at x = 2.0
    node = sensors(world, lidar={"beams": 360, "noise_stddev": 0.0})
    scan = measure(node, world_state(world, x=0.0, y=0.0, yaw=0.0))["/scan"]
    r = ranges(scan)
    ahead = int(round((0.0 - scan.angle_min) / scan.angle_increment))
    assert math.isclose(r[ahead], 2.0 - LASER_X, abs_tol=1e-3)
    assert scan.header.frame_id == "laser"
    assert len(r) == 360 and math.isclose(scan.angle_min, -math.pi)
    behind = 0  # -pi: nothing there, and the robot does not see itself
    assert math.isinf(r[behind]) and r[behind] > 0
    assert np.all(r[np.isfinite(r)] > 0.5)  # no self-hits on the robot's own geoms


def test_rotated_robot_sees_the_box_at_the_rotated_bearing(tmp_path):
    world = write_world(tmp_path, BOX.format(x=2.1))
    node = sensors(world, lidar={"beams": 360, "noise_stddev": 0.0})
    scan = measure(node, world_state(world, x=0.0, y=0.0, yaw=math.pi / 2))["/scan"]
    r = ranges(scan)
    right = int(round((-math.pi / 2 - scan.angle_min) / scan.angle_increment))
    assert math.isclose(r[right], 2.0, abs_tol=0.01)  # laser is 8 cm off-axis sideways now


def test_range_limits_follow_rep_117(tmp_path):
    world = write_world(tmp_path, BOX.format(x=2.1))
    node = sensors(world, lidar={"beams": 8, "fov": 0.2, "range_max": 1.5, "noise_stddev": 0})
    r = ranges(measure(node, world_state(world))["/scan"])
    assert np.all(np.isposinf(r))


def test_noise_is_seeded(tmp_path):
    world = write_world(tmp_path, BOX.format(x=2.1))
    state = world_state(world)
    params = {"lidar": {"beams": 90, "fov": 0.4, "noise_stddev": 0.05}}
    a = ranges(measure(sensors(world, seed=1, **params), state)["/scan"])
    b = ranges(measure(sensors(world, seed=1, **params), state)["/scan"])
    c = ranges(measure(sensors(world, seed=2, **params), state)["/scan"])
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert 0.01 < np.std(a - (2.0 - LASER_X) / np.cos(np.linspace(-0.2, 0.2, 90))) < 0.1


def test_point_cloud_hits_the_box(tmp_path):
    world = write_world(tmp_path, BOX.format(x=2.1))
    node = sensors(world, point_cloud={"beams": 180, "channels": 8, "noise_stddev": 0.0})
    cloud = measure(node, world_state(world))["/point_cloud"]
    pts = np.frombuffer(cloud.data, dtype=np.float32).reshape(-1, 4)
    assert cloud.width == len(pts) > 0 and cloud.point_step == 16
    assert [f.name for f in cloud.fields] == ["x", "y", "z", "intensity"]
    front = pts[(np.abs(pts[:, 1]) < 0.01) & (pts[:, 2] > -0.19)]  # lowest rings hit the floor
    assert len(front) >= 4
    assert np.allclose(front[:, 0], 2.0 - LASER_X, atol=1e-3)
    assert np.all((pts[:, 3] >= 0) & (pts[:, 3] <= 1.0001))


def test_wall_two_metres_away_reads_two_metres_in_the_depth_image(tmp_path):
    wall = f'<geom name="wall" type="box" pos="{2.0 + CAMERA_X + 0.05} 0 1" size="0.05 6 3"/>'
    world = write_world(tmp_path, wall)
    node = sensors(world, camera={"width": 160, "height": 120})
    out = measure(node, world_state(world))
    depth = out["/camera/depth/image_rect"]
    assert depth.encoding == "32FC1" and depth.step == 160 * 4
    img = np.frombuffer(depth.data, dtype=np.float32).reshape(120, 160)
    upper = img[:50]  # above the floor: only the wall; z-depth is the same at the corners
    assert np.allclose(upper, 2.0, atol=0.01)
    color = out["/camera/color/image_raw"]
    assert color.encoding == "rgb8" and color.step == 160 * 3
    assert len(color.data) == 160 * 120 * 3
    assert color.header.frame_id == depth.header.frame_id == "camera_color_optical_frame"


def test_camera_info_matches_the_image(tmp_path):
    world = write_world(tmp_path)
    node = sensors(world, camera={"width": 160, "height": 120})
    out = measure(node, world_state(world))
    info = out["/camera/camera_info"]
    assert (info.width, info.height) == (160, 120)
    f = 120 / 2 / math.tan(math.radians(60) / 2)  # robot.xml: fovy = 60 degrees
    k = list(info.k)
    assert math.isclose(k[0], f) and math.isclose(k[4], f)
    assert (k[2], k[5]) == (79.5, 59.5)
    assert list(info.p)[:3] == k[:3] and info.distortion_model == "plumb_bob"


def test_camera_projection_matches_intrinsics(tmp_path):
    # A thin post 2 m ahead and 0.5 m to the left shows up at u = cx - f * 0.5 / 2.
    post = f'<geom name="post" type="box" pos="{2.0 + CAMERA_X} 0.5 1" size="0.01 0.01 3"/>'
    world = write_world(tmp_path, post)
    out = measure(sensors(world, camera={"width": 160, "height": 120}), world_state(world))
    img = np.frombuffer(out["/camera/depth/image_rect"].data, np.float32).reshape(120, 160)
    cols = np.flatnonzero(np.isfinite(img[30]) & (img[30] < 3))
    k = list(out["/camera/camera_info"].k)
    assert abs(cols.mean() - (k[2] - k[0] * 0.5 / 2.0)) < 1.0


def test_world_state_of_another_world_is_refused(tmp_path):
    world = write_world(tmp_path)
    node = sensors(world, lidar={})
    bad = Float64MultiArray(data=[0.0] * 3)
    with pytest.raises(ValueError, match="does not match world"):
        measure(node, bad)


def test_outputs_follow_the_configured_sensors():
    lidar_only = SensorsNode.Params(lidar={})
    assert set(SensorsNode.outputs(lidar_only)) == {"/scan"}
    cam = SensorsNode.Params(camera={"depth": False})
    assert set(SensorsNode.outputs(cam)) == {"/camera/color/image_raw", "/camera/camera_info"}
    with pytest.raises(ValueError):
        SensorsNode.Params()


def test_camera_made_in_its_warm_up_thread_renders_the_same_pixels(tmp_path):
    # the renderer is made (and its first frame rendered) in a thread at set-up; the first
    # real render must give exactly what a renderer made on the spot gives
    wall = f'<geom name="wall" type="box" pos="{2.0 + CAMERA_X + 0.05} 0 1" size="0.05 6 3"/>'
    world = write_world(tmp_path, wall)
    state = world_state(world, x=0.3, y=0.0, yaw=0.2)
    warm = sensors(world, camera={"width": 160, "height": 120})
    assert warm.camera._warming is not None
    lazy = sensors(world, warm_up=False, camera={"width": 160, "height": 120})
    assert lazy.camera._warming is None
    for node in (warm, lazy):
        node.out = measure(node, state)
    for topic in ("/camera/color/image_raw", "/camera/depth/image_rect"):
        assert bytes(warm.out[topic].data) == bytes(lazy.out[topic].data)
    assert len(set(bytes(warm.out["/camera/color/image_raw"].data))) > 1  # not a blank frame


def test_sensor_nodes_of_one_process_share_one_mirror_and_measure_their_own_state(
        monkeypatch):
    """A swarm's lidars packed in one process pose one mirror of the world in turn: each scan
    is the one taken by the same node with a mirror of its own, given the same states."""
    from geometry_msgs.msg import Twist

    from descriptions.load import load_scenario
    from nodes.sensors.mirror import WorldMirror
    from orchestrator.lockstep.inprocess import make_node
    from tests.helpers import SCENARIOS

    sc = load_scenario(SCENARIOS / "swarm_small.yaml")
    physics = make_node(sc, "physics")
    go = Twist()
    go.linear.x, go.angular.z = 0.5, 1.0
    states = [physics.step(Tick(k, k * TICK), {"/robot_0/cmd_vel": go})["/cosim/world_state"]
              for k in range(30)]
    # robot 0 before and after it moved, robot 1 in between
    steps = [("lidar@robot_0", 0, states[0]), ("lidar@robot_1", 0, states[-1]),
             ("lidar@robot_0", 5, states[-1])]

    def scans():
        nodes = {name: make_node(sc, name) for name in ("lidar@robot_0", "lidar@robot_1")}
        out = [list(nodes[name].step(Tick(k, k * TICK), {"/cosim/world_state": state})
                    ["/scan"].ranges) for name, k, state in steps]
        return nodes, out

    nodes, shared = scans()
    assert nodes["lidar@robot_0"].mirror is nodes["lidar@robot_1"].mirror
    monkeypatch.setattr(WorldMirror, "shared", classmethod(
        lambda cls, w, lay=None, events=(): cls(w, lay, events)))
    nodes, own = scans()
    assert nodes["lidar@robot_0"].mirror is not nodes["lidar@robot_1"].mirror
    assert shared == own
    assert shared[0] != shared[2], "robot 0 did not move"


def _all_pairs_nearer(xpos, radius, origin, dirs, dist, range_max):
    """OtherRobots.nearer as it was written over every (beam, robot) pair: the reference
    for the one that computes only the pairs that may meet."""
    centres = xpos[:, :2] - origin[:2]
    c = centres[np.hypot(centres[:, 0], centres[:, 1]) <= range_max + radius]
    d = dirs[:, :2]
    a = (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])[:, None]
    b = d[:, :1] * c[:, 0] + d[:, 1:2] * c[:, 1]
    cc = (c[:, 0] * c[:, 0] + c[:, 1] * c[:, 1])[None, :] - radius ** 2
    disc = b * b - a * cc
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (b - np.sqrt(disc)) / a
    t = np.where((disc >= 0) & (t > 0) & (a > 1e-12), t, np.inf).min(axis=1)
    hit = t <= range_max
    return np.where(hit & ((dist < 0) | (t < dist)), t, dist)


def test_other_robots_shorten_the_beams_the_all_pairs_way_bit_for_bit():
    from nodes.sensors.others import OtherRobots

    class Data:
        model = None

    rng = np.random.default_rng(7)
    shortened = 0
    for trial in range(200):
        k, n, radius = int(rng.integers(1, 60)), int(rng.choice([180, 7, 48])), 0.23
        origin = np.array([*rng.uniform(-0.5, 0.5, 2), 0.2])
        xpos = np.zeros((k, 3))
        for j in range(k):  # half of them tangent to some beam (to within 1e-9)
            distance = rng.uniform(0.2, 9.0)
            off = rng.uniform(-math.pi, math.pi) if j % 2 else math.asin(
                min(1.0, radius / distance)) * (1 + rng.normal(0, 1e-9))
            heading = (int(rng.integers(n)) * 2 * math.pi / n) + off
            xpos[j, :2] = origin[:2] + distance * np.array([math.cos(heading),
                                                             math.sin(heading)])
        tilt = 0.0 if trial % 2 else 0.2
        angles = -math.pi + 2 * math.pi / n * np.arange(n) + rng.uniform(-3, 3)
        up = rng.uniform(-tilt, tilt, n)
        dirs = np.stack([np.cos(up) * np.cos(angles), np.cos(up) * np.sin(angles),
                         np.sin(up)], axis=1)
        dist = np.where(rng.random(n) < 0.3, -1.0, rng.uniform(0.0, 10.0, n))
        others = OtherRobots.__new__(OtherRobots)
        others.radius, others.bodies, others.model = radius, np.arange(k), None
        data = Data()
        data.xpos = xpos
        got = others.nearer(data, origin, dirs, dist, 8.0)
        want = _all_pairs_nearer(xpos, radius, origin, dirs, dist, 8.0)
        assert np.array_equal(got, want)
        shortened += int((want != dist).sum())
    assert shortened > 1000
