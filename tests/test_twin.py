"""A digital twin of a stand-in robot: a realtime physics node with a rosbridge server,
driven by a plain rclpy /cmd_vel publisher. The twin (scenarios/twin.yaml) mirrors the
robot's /odom at the tick each message entered; the stand-in killed and started again, the
twin reconnects and says so; the recorded session replays to one digest, twice
multi-process and once in-process. Bad twin input is exit 2 with nothing written."""

from __future__ import annotations

import json
import math
import os
import subprocess
import threading
import time

import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

from orchestrator.outputs.bag import BagReader
from runtime.recording import read_part
from tests.helpers import COSIM_NODE, ORCHESTRATE, ROOT
from tests.live_helpers import NAV, free_port, run_dir, wait_listening

TWIN = ROOT / "scenarios" / "twin.yaml"
TICK_NS = 20_000_000
HANG_S = 120  # generous guards against a hang, never a measured time


def standin(port: int, log) -> subprocess.Popen:
    """The stand-in robot: nav's physics, realtime, with a rosbridge server on ``port``."""
    proc = subprocess.Popen([*COSIM_NODE, "physics", "--scenario", str(NAV), "--realtime",
                             "--rosbridge", f"127.0.0.1:{port}"], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=log)
    wait_listening(port, proc)
    return proc


class Lines:
    """A process's stderr, read as it comes."""

    def __init__(self, proc: subprocess.Popen):
        self.lines: list[str] = []
        self.thread = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self.thread.start()

    def _read(self, proc) -> None:
        for line in proc.stderr:
            self.lines.append(line)

    def wait_for(self, text: str, proc: subprocess.Popen) -> None:
        """Until a line holds ``text`` (fail if the process ends first)."""
        deadline = time.monotonic() + HANG_S
        while not any(text in line for line in self.lines):
            assert proc.poll() is None, f"ended before {text!r}:\n{''.join(self.lines)}"
            assert time.monotonic() < deadline, f"no {text!r}:\n{''.join(self.lines)}"
            time.sleep(0.05)


class Driver:
    """A plain rclpy user: drives /cmd_vel in a circle, keeps the robot's own /odom."""

    def __init__(self, ros_node):
        self.node, self.executor = ros_node
        # stamp ns -> {(x, y)}: a restarted stand-in stamps from zero again
        self.odom: dict[int, set[tuple[float, float]]] = {}
        pub = self.node.create_publisher(Twist, "/cmd_vel", 10)
        twist = Twist()
        twist.linear.x, twist.angular.z = 0.3, 0.5
        self.node.create_timer(0.05, lambda: pub.publish(twist))
        self.node.create_subscription(Odometry, "/odom", self._odom, 50)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _odom(self, msg: Odometry) -> None:
        s = msg.header.stamp
        self.odom.setdefault(s.sec * 10**9 + s.nanosec, set()).add(
            (msg.pose.pose.position.x, msg.pose.pose.position.y))

    def _spin(self) -> None:
        while not self.stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()


@pytest.mark.alone  # a realtime robot on wall time: its /odom raced the other worker's load
def test_the_twin_mirrors_reconnects_and_replays(tmp_path, ros_node):
    port = free_port()
    log = open(tmp_path / "standin.log", "w")  # noqa: SIM115 - closed below
    robot = standin(port, log)
    driver = Driver(ros_node)
    # The twin reaches the robot over rosbridge only: on a domain of its own, its mirrored
    # /odom (stamped from zero, as the stand-in's) never mixes with the robot's in what the
    # rclpy user keeps (it did, and the user's queue then dropped the robot's at load)
    own_domain = {k: v for k, v in os.environ.items() if k != "ROS_DOMAIN_ID"}
    twin = subprocess.Popen([*ORCHESTRATE, str(TWIN), "--twin", f"ws://127.0.0.1:{port}",
                             "--duration", "20s", "--quiet", "--out", str(tmp_path / "twin")],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=own_domain)
    try:
        said = Lines(twin)
        said.wait_for("twin: connected to the robot", twin)
        wait_until(lambda: entered_so_far(tmp_path / "twin") >= 50, twin, said)
        robot.terminate()
        robot.wait(timeout=30)
        said.wait_for("twin: lost the robot", twin)
        robot = standin(port, log)
        said.wait_for("twin: reconnected to the robot", twin)
        twin.stdout.read()
        twin.wait(timeout=HANG_S)
    finally:
        driver.close()
        for proc in (robot, twin):
            if proc.poll() is None:
                proc.terminate()
                proc.wait(timeout=30)
        log.close()
    assert twin.returncode == 0, "".join(said.lines)
    told = "".join(said.lines)
    assert "twin: /odom is stale" in told and "twin: /odom is back after" in told
    recorded = run_dir(tmp_path / "twin")
    manifest = json.loads((recorded / "manifest.json").read_text())
    link = manifest["live"]["twin"]
    assert link["connects"] >= 2 and link["reconnects"] >= 1
    odom = link["topics"]["/odom"]
    assert odom["entered"] > 0 and odom["delay"]["n"] == odom["arrived"]
    assert odom["entry_wait"]["n"] == odom["entered"]
    assert link["topics"]["/scan"]["never_arrived"]  # the stand-in has no lidar
    assert odom["stale_periods"] >= 1 and odom["stale_s"] > 0  # while it was away
    # the chosen run topics went back (the stand-in refuses them: it takes only /cmd_vel)
    assert link["sent"]["/twin/scan"] > 0 and link["sent"]["/twin/odom"] > 0
    assert any("/twin/odom is not an input" in text for text in link["robot_errors"])

    # the mirror: at every tick a robot message entered, the twin's /odom is at its pose;
    # and what entered is the robot's own /odom (the rclpy user saw the same message)
    with BagReader(recorded / "bag") as bag:
        entered = {s // TICK_NS: m for s, m in bag.messages("/cosim/arrivals/real/odom",
                                                            Odometry)}
        mirrored = {s // TICK_NS: m for s, m in bag.messages("/odom", Odometry)}
        joints_in = {s // TICK_NS: m for s, m in bag.messages(
            "/cosim/arrivals/real/joint_states", JointState)}
        joints_out = {s // TICK_NS: m for s, m in bag.messages("/joint_states", JointState)}
    assert len(entered) == odom["entered"]
    held = None
    for tick in sorted(mirrored):
        real = entered.get(tick, held)
        held = real
        if real is None:
            continue
        got, want = mirrored[tick].pose.pose, real.pose.pose
        assert (got.position.x, got.position.y) == pytest.approx(
            (want.position.x, want.position.y), abs=1e-9), tick
        assert _yaw(got.orientation) == pytest.approx(_yaw(want.orientation), abs=1e-9)
    # the joints too (the wheels turned: their angles are the robot's)
    assert len(joints_in) > 10
    for tick, real in joints_in.items():
        assert list(joints_out[tick].name) == list(real.name)
        assert list(joints_out[tick].position) == pytest.approx(list(real.position), abs=1e-9)
    assert max(abs(p) for m in joints_in.values() for p in m.position[:2]) > 0.1
    # what entered is what the rclpy user saw at the same stamps, counted over both
    # stand-ins: either one's first messages may reach rosbridge before DDS discovery lets
    # the rclpy user see them (on a loaded machine, all of the first one's), and the second
    # stamps from zero again, so a stamp the user saw may be the other stand-in's
    matched = []
    for msg in entered.values():
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        p = msg.pose.pose.position
        if (p.x, p.y) in driver.odom.get(stamp, ()):
            matched.append(stamp)
    assert len(matched) > 10, (len(matched), len(driver.odom), len(entered))
    xs = [m.pose.pose.position.x for m in entered.values()]
    assert max(xs) - min(xs) > 0.05  # the driven robot moved, and the twin with it

    # replays: twice multi-process, once in-process: one digest
    digests = []
    for extra in ([], ["--in-process"], []):
        done = subprocess.run([*ORCHESTRATE, "--replay", str(recorded), "--quiet", "--out",
                               str(tmp_path / "replays"), *extra], cwd=ROOT,
                              capture_output=True, text=True, timeout=HANG_S * 2)
        assert done.returncode == 0, done.stderr
        digests.append(done.stdout.split("digest ")[1].split()[0])
    assert len(set(digests)) == 1
    assert digests[0] == manifest["digest"]  # lockstep, paced: the recorded run itself


def entered_so_far(out) -> int:
    """How many robot /odom messages the running twin has taken in (its external part)."""
    parts = list(out.glob("*/parts/external.rec"))
    if not parts:
        return 0
    return sum(topic == "/cosim/arrivals/real/odom" for _, topic, _ in read_part(parts[0]))


def wait_until(condition, proc: subprocess.Popen, said: Lines) -> None:
    """Until ``condition()`` holds (fail if ``proc`` ends first, or on a hang)."""
    deadline = time.monotonic() + HANG_S
    while not condition():
        assert proc.poll() is None and time.monotonic() < deadline, "".join(said.lines)
        time.sleep(0.05)


def _yaw(q) -> float:
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def test_no_robot_at_all_is_a_message_retries_and_a_failed_run(tmp_path):
    port = free_port()  # nothing listens there
    done = subprocess.run([*ORCHESTRATE, str(TWIN), "--twin", f"ws://127.0.0.1:{port}",
                           "--duration", "1s", "--in-process", "--quiet", "--out",
                           str(tmp_path / "out")], cwd=ROOT, capture_output=True, text=True,
                          timeout=HANG_S)
    assert done.returncode == 3, done.stderr  # a twin that never reached its robot failed
    assert f"twin: no robot at ws://127.0.0.1:{port}" in done.stderr
    assert f"twin: the robot at ws://127.0.0.1:{port} never answered" in done.stderr
    assert "Traceback" not in done.stderr
    link = json.loads((run_dir(tmp_path / "out") / "manifest.json").read_text())["live"]["twin"]
    assert link["connects"] == 0 and link["attempts"] >= 2  # it kept trying
    assert link["topics"]["/odom"]["never_arrived"]


@pytest.mark.parametrize("args, says", [
    (["--twin", "ws://127.0.0.1"], "needs a host and a port"),
    (["--twin", "http://127.0.0.1:9090"], "is not a ws:// address"),
    (["--twin", "ws://127.0.0.1:9", "--set", "twin.subscribe./odom=/odom"],
     "twin.subscribe./odom"),
    (["--twin", "ws://127.0.0.1:9", "--set", "twin.publish./nope=/x"], "no topic /nope"),
])
def test_bad_twin_input_is_exit_2_with_nothing_started(tmp_path, args, says):
    done = subprocess.run([*ORCHESTRATE, str(TWIN), "--out", str(tmp_path / "out"), *args],
                          cwd=ROOT, capture_output=True, text=True, timeout=HANG_S)
    assert done.returncode == 2 and says in done.stderr, done.stderr
    assert not (tmp_path / "out").exists()


def test_network_figures_losses_stale_and_clock_offsets():
    from orchestrator.proxies.twin import TopicStats

    stats = TopicStats("/odom", "/real/odom", stale_after_s=0.5)
    period = 0.02
    # a robot clock 1000 s behind ours, 3 ms + jitter on the way, messages 7..9 lost
    for k in range(30):
        if k in (7, 8, 9):
            continue
        stamp = 100.0 + k * period
        stats.arrival(now=k * period + 0.003, wall=1100.0 + k * period + 0.003 + 0.001 * (k % 2),
                      stamp=stamp)
    assert stats.lost == 3
    assert not stats.check_stale(now=30 * period)  # within stale_after of the last
    assert stats.check_stale(now=30 * period + 0.6) and stats.stale_periods == 1
    assert not stats.check_stale(now=30 * period + 0.7)  # one period, said once
    last = 29 * period + 0.003
    back = stats.arrival(now=last + 1.0, wall=1100.0 + 31 * period + 0.003,
                         stamp=100.0 + 31 * period)
    assert back == pytest.approx(0.5, abs=1e-6)  # stale from the last + 0.5 s till now
    summary = stats.summary(now=2.0)
    assert summary["clock"] == "offset"  # 1000 s apart: not one clock
    assert summary["delay"]["p50_ms"] == pytest.approx(0.0, abs=0.01)  # above the fastest
    assert summary["delay"]["max_ms"] == pytest.approx(1.0, abs=0.01)
    assert summary["stale_periods"] == 1 and not summary["stale_at_end"]
    # a restarted robot stamps from zero: its own fastest message is its own baseline
    stats.new_connection()
    for k in range(5):
        stats.arrival(now=3.0 + k * period, wall=5000.0 + k * period, stamp=k * period + 0.01)
    assert stats.summary(now=4.0)["delay"]["max_ms"] == pytest.approx(1.0, abs=0.01)
