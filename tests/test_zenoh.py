"""The zenoh transport: same digests as in-process and ros2, same fault handling, other hosts."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import psutil
import pytest
import yaml

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from plan.timeutil import parse_duration_ns
from runtime.transport.zenoh import liveliness_key, topic_key, type_hash
from tests.helpers import ORCHESTRATE, ROOT, SCENARIOS, node_process, orchestrate

LONG = SCENARIOS / "long_chain.yaml"
# Every scenario is compared over zenoh for its first seconds only: what is under test is the
# transport, and a divergence shows within the first ticks that exchange messages (whole runs
# are compared in-process and over ros2 by tests/test_swarm.py and the scenario tests).
SHORT = {"long_chain.yaml": "1s", "swarm.yaml": "1s", "swarm_urdf.yaml": "1s"}
FIRST_SECONDS = "2s"
# Scenarios whose every node kind and topic the others already send over zenoh, left out for
# the suite's time (seconds it would add on 2 cores): why each adds nothing.
COVERED = {"cluttered.yaml": "nav's nodes and topics in another world (4 s)",
           "corridor.yaml": "nav's nodes and topics in another world (4 s)",
           "u_trap.yaml": "nav's nodes and topics in another world (4 s)",
           "nav_usd.yaml": "nav's nodes and topics, the world from a USD stage (6 s)",
           "meshbot.yaml": "nav_urdf's nodes and topics, a robot with mesh files (5 s)",
           "worldarm.yaml": "arm's nodes and topics, the arm placed by its world (4 s)",
           "nav_spawn.yaml": "spawn_short's object events over nav's nodes (5 s)",
           "swarm_small.yaml": "swarm's nodes and topics with four robots, compared over "
           "zenoh across two hosts and network namespaces below (8 s)",
           "swarm_urdf_control.yaml": "swarm_urdf's robots and nodes with nav_urdf_control's "
           "controller manager per robot; namespacing is the plan's, not the transport's (14 s)",
           "ur5e_control.yaml": "arm_urdf's nodes and topics with arm_control's trajectory "
           "controller, in a manager per robot as swarm_urdf_control's (6 s)",
           # a robot's description format changes the physics, not what crosses the transport
           "swarm_usd.yaml": "swarm's nodes and topics, its robots from a USD stage (14 s)",
           "swarm_usd_robots.yaml": "swarm_urdf's nodes and topics, robots described in USD "
           "(14 s)",
           # crowds: swarm's kinds and topics, the controllers also reading the world state
           "crowd_door.yaml": "swarm's nodes and topics; /cosim/world_state to controllers as "
           "to lidars (compared packed in tests/test_crowd.py)",
           "crowd_plaza.yaml": "crowd_door's nodes and topics in another world",
           # robots that enter: windows are the schedule's, the same for every transport
           "swarm_enter.yaml": "swarm's nodes and topics, robots entering and leaving at "
           "events (one digest over zenoh checked by hand, 10 s)",
           "swarm_clients.yaml": "swarm_enter's, the robots clients may bring in dormant "
           "without a client (8 s)",
           "nav_usd_robot.yaml": "nav_urdf's nodes and topics, the robot in USD (4 s)",
           "arm_usd.yaml": "arm_urdf's nodes and topics, the arm in USD (3 s)"}


def all_scenarios() -> list[Path]:
    """Every scenario of the repository that cosim runs alone (no foreign ROS 2 program, no
    robot of a digital twin to connect to)."""
    out = []
    for path in sorted([*(ROOT / "scenarios").glob("*.yaml"), *SCENARIOS.glob("*.yaml")]):
        doc = yaml.safe_load(path.read_text())
        if "twin" not in doc and not any("command" in node for node in doc.get("nodes", [])) \
                and path.name not in COVERED:
            out.append(path)
    return out


def first_seconds(path: Path) -> str:
    """How much of ``path`` the zenoh comparison runs: SHORT's figure, else FIRST_SECONDS or
    the scenario's own duration where that is shorter, and past its last event (a spawn at
    5 s is compared over zenoh too)."""
    if path.name in SHORT:
        return SHORT[path.name]
    doc = yaml.safe_load(path.read_text())
    last_event = max((parse_duration_ns(e["at"]) for e in doc.get("events") or []), default=0)
    first = max(parse_duration_ns(FIRST_SECONDS), last_event + 1_000_000_000)
    own = parse_duration_ns(doc["duration"])
    return doc["duration"] if own < first else f"{first // 1_000_000_000}s"


def test_keys_follow_rmw_zenoh_and_carry_the_domain():
    from rosgraph_msgs.msg import Clock

    assert type_hash(Clock).startswith("RIHS01_")
    assert topic_key("/clock", Clock, 5) == (
        "5/clock/rosgraph_msgs::msg::dds_::Clock_/" + type_hash(Clock))
    assert liveliness_key("pub", "/cosim/status", "cosim_a", 5) == (
        "@cosim/5/pub/cosim/status/cosim_a")


@pytest.mark.parametrize("path", all_scenarios(), ids=lambda p: p.stem)
def test_digest_over_zenoh_equals_in_process(tmp_path, path):
    duration = first_seconds(path)
    run = orchestrate(path, tmp_path, "--transport", "zenoh", "--duration", duration)
    assert run.code in (0, 1), run.stderr
    in_process = run_in_process(load_scenario(path, {"duration": duration}))
    assert run.manifest["digest"] == in_process.digest


def test_protocol_digest_is_the_same_over_zenoh_ros2_and_in_process(tmp_path):
    path = SCENARIOS / "protocol.yaml"
    digests = {}
    for transport in ("zenoh", "ros2"):
        run = orchestrate(path, tmp_path / transport, "--transport", transport)
        assert run.code == 0, run.stderr
        digests[transport] = run.manifest["digest"]
    digests["in-process"] = run_in_process(load_scenario(path)).digest
    assert len(set(digests.values())) == 1, digests


def test_sigkill_mid_run_over_zenoh_exits_3_naming_node_and_tick(tmp_path):
    proc = subprocess.Popen([*ORCHESTRATE, str(LONG), "--out",
                             str(tmp_path), "--transport", "zenoh"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 60
        while not (parts := list(tmp_path.glob("*/parts/tail.rec"))) or \
                parts[0].stat().st_size < 2000:
            assert proc.poll() is None and time.monotonic() < end, proc.communicate()
            time.sleep(0.05)
        victim = node_process(proc.pid, "middle")
        nodes = psutil.Process(proc.pid).children(recursive=True)
        victim.send_signal(signal.SIGKILL)
        _, err = proc.communicate(timeout=60)  # a hang guard; the bag is written before exit
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    _, left = psutil.wait_procs(nodes, timeout=10)
    assert not left, f"still running: {[p.pid for p in left]}"
    assert proc.returncode == 3, err
    assert "node middle died at tick" in err and "(killed by signal SIGKILL)" in err


# -- two network namespaces joined by a veth pair: nodes on "another host" -------------------


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True)


@pytest.fixture
def two_hosts():
    """Namespaces A (10.77.N.1) and B (10.77.N.2) joined by a veth pair; removed afterwards."""
    if os.geteuid() != 0 or shutil.which("ip") is None:
        reason = "needs root and iproute2 to make network namespaces"
        print(f"skipped: {reason}")
        pytest.skip(reason)
    n = os.getpid() % 250 + 1
    a, b = f"cosim{os.getpid()}a", f"cosim{os.getpid()}b"
    veth_a, veth_b = f"cz{os.getpid()}a"[:15], f"cz{os.getpid()}b"[:15]
    try:
        _ip("netns", "add", a)
        _ip("netns", "add", b)
        _ip("link", "add", veth_a, "type", "veth", "peer", "name", veth_b)
        for ns, dev, host in ((a, veth_a, 1), (b, veth_b, 2)):
            _ip("link", "set", dev, "netns", ns)
            _ip("-n", ns, "addr", "add", f"10.77.{n}.{host}/24", "dev", dev)
            _ip("-n", ns, "link", "set", dev, "up")
            _ip("-n", ns, "link", "set", "lo", "up")
    except (subprocess.CalledProcessError, OSError) as exc:
        _remove_namespaces(a, b)
        reason = f"cannot make network namespaces here: {getattr(exc, 'stderr', exc)!r}"
        print(f"skipped: {reason}")
        pytest.skip(reason)
    try:
        yield a, b, f"10.77.{n}.1"
    finally:
        _remove_namespaces(a, b)


def _remove_namespaces(*names: str) -> None:
    for ns in names:
        pids = subprocess.run(["ip", "netns", "pids", ns], capture_output=True, text=True)
        for pid in pids.stdout.split():
            try:
                os.kill(int(pid), signal.SIGKILL)
            except (OSError, ValueError):
                pass
        subprocess.run(["ip", "netns", "del", ns], capture_output=True)


@pytest.mark.parametrize("name", ["protocol", "nav", "swarm"])
def test_nodes_in_another_network_namespace_over_tcp_give_the_same_digest(tmp_path, two_hosts,
                                                                          name):
    ns_a, ns_b, address = two_hosts
    path = {"protocol": SCENARIOS / "protocol.yaml", "nav": ROOT / "scenarios/nav.yaml",
            "swarm": SCENARIOS / "swarm_small.yaml"}[name]
    scenario = load_scenario(path)
    moved = list(scenario.nodes)[1::2]  # every other node runs in namespace B
    instances = moved
    if name == "swarm":  # every robot's lidar (a template: its prefix goes to each instance)
        moved, instances = ["lidar"], [n for n in scenario.nodes if n.startswith("lidar@")]
    # each moved node's launch prefix (a scenario key) enters namespace B and says so
    prefixes = [f"nodes.{node}.prefix=ip netns exec {ns_b} sh -c 'ip netns identify "
                f"> {tmp_path}/{node}.netns; exec \"$@\"' sh" for node in moved]
    endpoint = f"tcp/{address}:7447"
    proc = subprocess.run(
        ["ip", "netns", "exec", ns_a, *ORCHESTRATE, str(path),
         "--out", str(tmp_path), "--transport", "zenoh", "--quiet",
         "--set", f"zenoh.listen={json.dumps([endpoint])}",
         *[arg for prefix in prefixes for arg in ("--set", prefix)]],
        cwd=ROOT, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr
    manifest = json.loads(next(tmp_path.glob("*/manifest.json")).read_text())
    assert manifest["digest"] == run_in_process(scenario).digest
    logs = next(tmp_path.glob("*/logs"))
    assert all((logs / f"{node}.log").exists() for node in instances)
    assert {(tmp_path / f"{node}.netns").read_text().strip() for node in moved} == {ns_b}


def _split_swarm(tmp_path: Path) -> Path:
    """swarm_small with its per-robot templates split in two: robots 0 and 1 keep 'lidar' and
    'control', robots 2 and 3 get copies named 'lidar_b' and 'control_b' (the ones to move)."""
    doc = yaml.safe_load((SCENARIOS / "swarm_small.yaml").read_text())
    doc["world"] = str((SCENARIOS / doc["world"]).resolve())
    doc["robots"]["description"] = str((SCENARIOS / doc["robots"]["description"]).resolve())
    robots = [f"robot_{i}" for i in range(doc["robots"]["count"])]
    half = len(robots) // 2
    split = []
    for node in doc["nodes"]:
        if node.get("for_each") == "robot":
            split.append({**node, "robots": robots[:half]})
            split.append({**node, "name": node["name"] + "_b", "robots": robots[half:]})
        else:
            split.append(node)
    doc["nodes"], doc["name"] = split, "swarm_split"
    path = tmp_path / "swarm_split.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_swarm_split_across_two_hosts_over_zenoh_gives_the_in_process_digest(tmp_path, two_hosts):
    """The orchestrator, physics and robots 0-1 in namespace A; robots 2-3 (lidar and
    controller each) in namespace B, linked over TCP on the veth pair only."""
    ns_a, ns_b, address = two_hosts
    path = _split_swarm(tmp_path)
    scenario = load_scenario(path)
    moved = ["lidar_b", "control_b"]
    instances = [n for n in scenario.nodes if n.split("@")[0] in moved]
    assert len(instances) == 4 and len(scenario.nodes) == 9
    prefixes = [f"nodes.{node}.prefix=ip netns exec {ns_b} sh -c 'ip netns identify "
                f"> {tmp_path}/{node}.netns; exec \"$@\"' sh" for node in moved]
    proc = subprocess.run(
        ["ip", "netns", "exec", ns_a, *ORCHESTRATE, str(path),
         "--out", str(tmp_path / "out"), "--transport", "zenoh", "--quiet", "--duration", "2s",
         "--set", f"zenoh.listen={json.dumps([f'tcp/{address}:7447'])}",
         *[arg for prefix in prefixes for arg in ("--set", prefix)]],
        cwd=ROOT, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr
    manifest = json.loads(next(tmp_path.glob("out/*/manifest.json")).read_text())
    assert manifest["digest"] == run_in_process(load_scenario(path, {"duration": "2s"})).digest
    logs = next(tmp_path.glob("out/*/logs"))
    assert all((logs / f"{node}.log").exists() for node in instances)
    assert {(tmp_path / f"{node}.netns").read_text().strip() for node in moved} == {ns_b}


def test_mirror_to_dds_lets_ros2_tools_watch_a_zenoh_run(tmp_path):
    import rclpy
    import rclpy.executors
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Int64

    from runtime.transport.ros2 import use_cosim_dds_profile

    use_cosim_dds_profile()
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("watcher", context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    seen: list[int] = []
    node.create_subscription(Int64, "/source", lambda m: seen.append(m.data),
                             QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    proc = subprocess.Popen([*ORCHESTRATE,
                             str(SCENARIOS / "protocol.yaml"), "--out", str(tmp_path),
                             "--transport", "zenoh", "--duration", "5s", "--quiet",
                             "--set", 'zenoh.mirror_to_dds=["/source"]'],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        while proc.poll() is None:
            executor.spin_once(timeout_sec=0.05)
        _, err = proc.communicate()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
    assert proc.returncode == 0, err
    assert len(seen) > 100  # 500 published at 100 Hz; DDS discovery may miss the first ones


def test_foreign_programs_over_zenoh_are_refused_before_anything_starts(tmp_path):
    run = orchestrate(SCENARIOS / "foreign_echo.yaml", tmp_path, "--transport", "zenoh")
    assert run.code == 2
    assert "foreign ROS 2 programs" in run.stderr and "echo" in run.stderr
    assert not list(tmp_path.glob("*"))
