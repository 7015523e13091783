"""/tf, /tf_static, /imu and a stamped /cmd_vel in real runs: a plain rclpy reader during a
multi-process nav run, the run's bag read back with rosbags, seeded IMU noise, TwistStamped
end to end, the type mismatch refused at load, and a reset that latches /tf_static again."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.typesys import Stores, get_typestore

from descriptions.load import load_scenario
from orchestrator.api import run
from tests.helpers import ORCHESTRATE, ROOT, orchestrate
from tests.test_sim_control import call, wait_paused_at

NAV = ROOT / "scenarios" / "nav.yaml"
WORLD = ROOT / "scenarios" / "worlds" / "nav.xml"
STATIC_FRAMES = {"laser": "base_link", "imu_link": "base_link", "camera_link": "tilt_link",
                 "camera_color_optical_frame": "camera_link",
                 "camera_depth_optical_frame": "camera_link"}
SENSOR_TOPICS = ("/scan", "/camera/camera_info", "/camera/depth/image_rect",
                 "/camera/color/image_raw")


def stamp_ns(stamp) -> int:
    """A builtin_interfaces/Time (rclpy or rosbags) in nanoseconds."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def yaw(q) -> float:
    """Heading of a quaternion with x, y, z, w fields."""
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def assert_tf_matches_odom(tf_msg, odom) -> None:
    """odom -> base_link in ``tf_msg`` is exactly the pose ``odom`` carries, at its stamp."""
    base = [t for t in tf_msg.transforms if t.child_frame_id == "base_link"]
    assert len(base) == 1 and base[0].header.frame_id == "odom"
    t, p = base[0].transform, odom.pose.pose
    assert stamp_ns(base[0].header.stamp) == stamp_ns(odom.header.stamp)
    assert (t.translation.x, t.translation.y, t.translation.z) == \
        (p.position.x, p.position.y, p.position.z)
    assert (t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w) == \
        (p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w)


def root_of(frame: str, parents: dict[str, str]) -> str:
    """Walk a frame up its parents to the tree's root (fails on a loop)."""
    seen = set()
    while frame in parents:
        assert frame not in seen, f"TF loop at {frame}"
        seen.add(frame)
        frame = parents[frame]
    return frame


@dataclass
class Watched:
    """What a plain rclpy program saw during a multi-process run, and the run itself."""

    run_dir: Path
    ticks: int
    digest: str
    odom: dict[int, object] = field(default_factory=dict)
    tf: dict[int, object] = field(default_factory=dict)
    frame_ids: dict[str, set[str]] = field(default_factory=dict)
    static_latched: list = field(default_factory=list)
    static_volatile: list = field(default_factory=list)


@pytest.fixture(scope="module")
def watched(tmp_path_factory) -> Watched:
    """1 s of nav, every node its own process, watched by a plain rclpy node: it subscribes
    to /odom, /tf and the sensors before tick 0, and to /tf_static only after tick 0 was
    published (once transient-local, once volatile)."""
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import CameraInfo, Image, LaserScan
    from std_srvs.srv import SetBool, Trigger
    from tf2_msgs.msg import TFMessage

    out = tmp_path_factory.mktemp("watched")
    proc = subprocess.Popen([*ORCHESTRATE, str(NAV), "--paused", "--duration", "1s",
                             "--quiet", "--out", str(out)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("tf_reader", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    seen = Watched(out, 0, "")
    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    try:
        subs = [node.create_subscription(Odometry, "/odom", lambda m: seen.odom.setdefault(
                    stamp_ns(m.header.stamp), m), reliable),
                node.create_subscription(TFMessage, "/tf", lambda m: seen.tf.setdefault(
                    stamp_ns(m.transforms[0].header.stamp), m), reliable)]
        for topic, msg_type in zip(SENSOR_TOPICS, (LaserScan, CameraInfo, Image, Image),
                                   strict=True):
            subs.append(node.create_subscription(
                msg_type, topic, lambda m, t=topic: seen.frame_ids.setdefault(t, set()).add(
                    m.header.frame_id), reliable))
        ros = (node, executor)
        call(ros, SetBool, "/cosim/pause", SetBool.Request(data=True))  # it is up
        spin_until(executor, lambda: all(s.get_publisher_count() for s in subs), 30)
        spin_until(executor, lambda: False, 0.5)  # let the publishers match us too
        assert call(ros, Trigger, "/cosim/step", Trigger.Request()).success
        spin_until(executor, lambda: 0 in seen.odom, 30)
        assert wait_paused_at(ros, 1)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(TFMessage, "/tf_static", seen.static_latched.append, latched)
        node.create_subscription(TFMessage, "/tf_static", seen.static_volatile.append, reliable)
        spin_until(executor, lambda: seen.static_latched, 30)
        spin_until(executor, lambda: False, 0.5)
        call(ros, SetBool, "/cosim/pause", SetBool.Request(data=False))
        spin_until(executor, lambda: proc.poll() is not None, 120)
        spin_until(executor, lambda: False, 0.3)
        stdout, stderr = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
    assert proc.returncode in (0, 1), stderr
    seen.run_dir = next(out.glob("nav-*"))
    manifest = json.loads((seen.run_dir / "manifest.json").read_text())
    seen.ticks, seen.digest = manifest["ticks"], manifest["digest"]
    return seen


def spin_until(executor, done, timeout: float) -> None:
    """Spin ``executor`` until ``done()`` or ``timeout`` seconds (then simply return)."""
    end = time.monotonic() + timeout
    while not done() and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.02)


def test_tf_reader_sees_odom_to_base_link_equal_to_odom_at_every_stamp(watched):
    assert len(watched.odom) == watched.ticks == 51
    assert sorted(watched.tf) == sorted(watched.odom) == [k * 20_000_000 for k in range(51)]
    for stamp, odom in watched.odom.items():
        tf = watched.tf[stamp]
        assert {stamp_ns(t.header.stamp) for t in tf.transforms} == {stamp}
        assert_tf_matches_odom(tf, odom)
    first = {t.child_frame_id: t.header.frame_id for t in watched.tf[0].transforms}
    assert first == {"odom": "map", "base_link": "odom", "pan_link": "base_link",
                     "tilt_link": "pan_link"}


def test_a_late_subscriber_gets_tf_static_only_with_transient_local_durability(watched):
    # tf_static is published once, at tick 0: a volatile subscriber made later is sent
    # nothing new (Fast DDS may still hand it the writer's one kept sample when the two match
    # while that sample is being repaired: seen once on a loaded machine)
    assert len(watched.static_volatile) <= 1
    assert all(stamp_ns(t.header.stamp) == 0
               for msg in watched.static_volatile for t in msg.transforms)
    assert len(watched.static_latched) == 1
    static = watched.static_latched[0].transforms
    assert {t.child_frame_id: t.header.frame_id for t in static} == STATIC_FRAMES
    assert {stamp_ns(t.header.stamp) for t in static} == {0}


def test_every_frame_the_sensors_stamp_is_in_the_tf_tree(watched):
    parents = {t.child_frame_id: t.header.frame_id
               for msg in (watched.static_latched[0], watched.tf[0]) for t in msg.transforms}
    assert watched.frame_ids == {"/scan": {"laser"},
                                 "/camera/camera_info": {"camera_color_optical_frame"},
                                 "/camera/depth/image_rect": {"camera_color_optical_frame"},
                                 "/camera/color/image_raw": {"camera_color_optical_frame"}}
    for frames in watched.frame_ids.values():
        for frame in frames:
            assert root_of(frame, parents) == "map", frame
    assert root_of("imu_link", parents) == "map"


def test_multi_process_digest_equals_in_process(watched, tmp_path):
    reference = run(NAV, in_process=True, out=tmp_path, duration="1s", picture=False)
    assert watched.digest == reference.digest


class Bag:
    """A run's bag read with rosbags alone: connections by topic, messages decoded."""

    def __init__(self, run_dir: Path):
        self.reader = AnyReader([run_dir / "bag"],
                                default_typestore=get_typestore(Stores.ROS2_JAZZY))
        self.reader.open()
        self.connections = {c.topic: c for c in self.reader.connections}

    def messages(self, topic: str) -> list[tuple[int, object]]:
        """(log time, rosbags message) of ``topic``."""
        conn = self.connections[topic]
        return [(t, self.reader.deserialize(raw, conn.msgtype))
                for _, t, raw in self.reader.messages(connections=[conn])]

    def close(self) -> None:
        """Close the reader."""
        self.reader.close()


def test_bag_holds_tf_tf_static_latched_and_imu(watched):
    bag = Bag(watched.run_dir)
    try:
        static_conn = bag.connections["/tf_static"]
        assert static_conn.msgtype == "tf2_msgs/msg/TFMessage"
        (qos,) = static_conn.ext.offered_qos_profiles
        assert qos.durability == QosDurability.TRANSIENT_LOCAL
        assert qos.reliability == QosReliability.RELIABLE and qos.depth == 1
        assert bag.connections["/tf"].ext.offered_qos_profiles == []
        static = bag.messages("/tf_static")
        assert [t for t, _ in static] == [0]
        assert {t.child_frame_id: t.header.frame_id
                for t in static[0][1].transforms} == STATIC_FRAMES
        odom = dict(bag.messages("/odom"))
        tf = bag.messages("/tf")
        assert [t for t, _ in tf] == sorted(odom) and len(tf) == watched.ticks
        for log_time, msg in tf:
            assert {stamp_ns(t.header.stamp) for t in msg.transforms} == {log_time}
            assert_tf_matches_odom(msg, odom[log_time])
        imu = bag.messages("/imu")
        assert [t for t, _ in imu] == sorted(odom)
        for log_time, msg in imu:
            assert msg.header.frame_id == "imu_link" and stamp_ns(msg.header.stamp) == log_time
            error = (yaw(msg.orientation) - yaw(odom[log_time].pose.pose.orientation)
                     + math.pi) % (2 * math.pi) - math.pi
            assert abs(error) < 0.02  # orientation noise 0.002 rad per axis
            for name, stddev in (("orientation", 0.002), ("angular_velocity", 0.002),
                                 ("linear_acceleration", 0.02)):
                cov = np.reshape(getattr(msg, f"{name}_covariance"), (3, 3))
                np.testing.assert_array_equal(cov, np.diag([stddev ** 2] * 3))
        driving = [msg.linear_acceleration.z for t, msg in imu if t >= 200_000_000]
        assert all(9.3 < z < 10.3 for z in driving)  # on the flat floor: gravity, mostly
    finally:
        bag.close()


def still_scenario(tmp_path: Path) -> Path:
    """Physics alone, no command: the robot settles and stands still for 2 s."""
    path = tmp_path / "still.yaml"
    path.write_text(yaml.safe_dump({
        "name": "still", "seed": 1, "duration": "2s", "world": str(WORLD),
        "nodes": [{"name": "physics", "kind": "physics", "rate": 50,
                   "params": {"start": {"x": -3.0, "y": -3.0, "yaw": 0.785}}}]}))
    return path


def raw_messages(run_dir: Path, topic: str) -> list[bytes]:
    """The CDR bytes of ``topic`` in a run's bag."""
    bag = Bag(run_dir)
    try:
        return [raw for _, _, raw in bag.reader.messages(connections=[bag.connections[topic]])]
    finally:
        bag.close()


def test_imu_at_rest_in_the_bag_reads_gravity_and_its_noise_is_seeded(tmp_path):
    still = still_scenario(tmp_path)
    runs = [run(still, in_process=True, out=tmp_path / str(i), seed=seed, picture=False)
            for i, seed in enumerate((1, 1, 2))]
    imu = [raw_messages(r.run_dir, "/imu") for r in runs]
    assert len(imu[0]) == 101 and imu[0] == imu[1] and imu[0] != imu[2]
    assert all(a != b for a, b in zip(imu[0], imu[2], strict=True))
    odom = [raw_messages(r.run_dir, "/odom") for r in runs]
    assert odom[0] == odom[2]  # the noise is the IMU's alone
    bag = Bag(runs[0].run_dir)
    try:
        rest = [m for t, m in bag.messages("/imu") if t >= 1_000_000_000]
    finally:
        bag.close()
    accel = np.array([[m.linear_acceleration.x, m.linear_acceleration.y,
                       m.linear_acceleration.z] for m in rest])
    assert abs(accel[:, 2].mean() - 9.81) < 0.05 and np.abs(accel[:, :2].mean(0)).max() < 0.05
    assert abs(np.mean([yaw(m.orientation) for m in rest]) - 0.785) < 0.01


def test_twist_stamped_drives_the_robot_across_processes(tmp_path):
    stamped = ("--set", "nodes.physics.params.enable_stamped_cmd_vel=true",
               "--set", "nodes.control.params.enable_stamped_cmd_vel=true")
    cli = orchestrate(NAV, tmp_path / "multi", "--duration", "4s", *stamped)
    assert cli.code in (0, 1), cli.stderr
    bag = Bag(cli.run_dir)
    try:
        assert bag.connections["/cmd_vel"].msgtype == "geometry_msgs/msg/TwistStamped"
        commands = bag.messages("/cmd_vel")
        assert all(m.header.frame_id == "base_link" and stamp_ns(m.header.stamp) == t
                   for t, m in commands)
        assert max(m.twist.linear.x for _, m in commands) > 0.2
        odom = [m.pose.pose.position for _, m in bag.messages("/odom")]
    finally:
        bag.close()
    assert math.hypot(odom[-1].x - odom[0].x, odom[-1].y - odom[0].y) > 0.3
    reference = run(load_scenario(NAV, {
        "duration": "4s", "nodes.physics.params.enable_stamped_cmd_vel": True,
        "nodes.control.params.enable_stamped_cmd_vel": True}), in_process=True,
        out=tmp_path / "in", picture=False)
    assert cli.manifest["digest"] == reference.digest


def test_a_cmd_vel_type_mismatch_exits_2_naming_the_key_and_writes_nothing(tmp_path):
    out = tmp_path / "runs"
    cli = orchestrate(NAV, out, "--set", "nodes.control.params.enable_stamped_cmd_vel=true")
    assert cli.code == 2
    assert "nodes[0] (physics).params.enable_stamped_cmd_vel" in cli.stderr
    assert "TwistStamped" in cli.stderr and "Traceback" not in cli.stderr
    assert not out.exists() or not any(out.iterdir())


def test_a_reset_latches_tf_static_again_and_equals_a_fresh_run(tmp_path, ros_node):
    from std_srvs.srv import SetBool, Trigger

    proc = subprocess.Popen([*ORCHESTRATE, str(NAV), "--paused", "--duration", "1s",
                             "--quiet", "--out", str(tmp_path / "runs")], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        for _ in range(3):
            assert call(ros_node, Trigger, "/cosim/step", Trigger.Request()).success
        assert wait_paused_at(ros_node, 3)
        assert call(ros_node, Trigger, "/cosim/reset", Trigger.Request()).success
        call(ros_node, SetBool, "/cosim/pause", SetBool.Request(data=False))
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode in (0, 1), err
    run_dir = next((tmp_path / "runs").glob("nav-*"))
    reference = run(NAV, in_process=True, out=tmp_path / "in", duration="1s", picture=False)
    assert reference.digest in out
    assert len(raw_messages(run_dir, "/tf_static")) == 1
    assert raw_messages(run_dir, "/tf_static") == raw_messages(reference.run_dir, "/tf_static")


@pytest.mark.parametrize("kind", ["ros2", "zenoh"])
def test_a_latched_publisher_serves_subscriptions_made_after_it_published(kind):
    from std_msgs.msg import Int64

    from plan.options import TransportSettings
    from runtime.cdr.encode import encode
    from runtime.transport.factory import create_transport

    settings = TransportSettings(kind=kind)
    publisher_side = create_transport(settings, f"latch_pub_{kind}")
    reader_side = create_transport(settings, f"latch_sub_{kind}")
    try:
        pub = publisher_side.publisher("/cosim_test/latched", Int64, 1, latched=True)
        pub.publish(encode(Int64(data=42)))
        late = reader_side.subscription("/cosim_test/latched", Int64, 1, latched=True)
        end = time.monotonic() + 20
        got = []
        while time.monotonic() < end and not got:
            got += reader_side.wait(50_000_000)
        # The sample has reached this side, so it has left the publisher (zenoh batches, and a
        # subscription declared before the batch went out is sent it live: that is not
        # latching): a volatile subscription made now gets nothing, the latched one no copy
        volatile = reader_side.subscription("/cosim_test/latched", Int64, 1)
        end = time.monotonic() + 20
        while time.monotonic() < end and not volatile.matched():
            got += reader_side.wait(50_000_000)
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            got += reader_side.wait(50_000_000)
        assert late.matched() == volatile.matched() == 1
        assert [r.data for r in got] == [encode(Int64(data=42))]
    finally:
        reader_side.close()
        publisher_side.close()


def test_realtime_physics_latches_tf_static_for_a_late_subscriber(ros_node):
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from tf2_msgs.msg import TFMessage

    from tests.helpers import COSIM_NODE

    node, executor = ros_node
    odoms, static = [], []
    node.create_subscription(Odometry, "/odom", odoms.append, 10)
    physics = subprocess.Popen([*COSIM_NODE, "physics", "--scenario", str(NAV), "--realtime",
                                "--rtf", "2"], cwd=ROOT, stderr=subprocess.PIPE, text=True)
    try:
        spin_until(executor, lambda: len(odoms) > 5, 30)
        assert odoms, "no /odom from the standalone physics node"
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(TFMessage, "/tf_static", static.append, latched)
        spin_until(executor, lambda: static, 20)
    finally:
        physics.send_signal(signal.SIGINT)
        _, err = physics.communicate(timeout=10)
    assert physics.returncode == 0, err
    assert len(static) == 1
    assert {t.child_frame_id: t.header.frame_id for t in static[0].transforms} == STATIC_FRAMES
