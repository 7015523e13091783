"""rosbridge (--rosbridge) with clients nobody here wrote: roslibjs (npm "roslib", under node)
and roslibpy (PyPI) drive a lockstep run and a standalone realtime physics node; messages a
client publishes enter the run at a tick and are recorded, so the run replays to the same
digest; bad frames get an error status and the connection stays open."""

from __future__ import annotations

import json
import re
import signal
import socket
import time
from types import SimpleNamespace

import pytest
import roslibpy
from websockets.sync.client import connect

from orchestrator import api
from orchestrator.api import load, run
from orchestrator.outputs.bag import BagReader
from tests.live_helpers import (
    NAV,
    cosim_node,
    drive_scenario,
    finish,
    free_port,
    manifest,
    node_client,
    orchestrate,
    run_dir,
    summary,
    wait_listening,
)

HANG_S = 60  # generous: only a hang runs into it, however loaded the machine


def roslibpy_client(port: int) -> roslibpy.Ros:
    ros = roslibpy.Ros(host="127.0.0.1", port=port)
    ros.run(timeout=10)
    return ros


def replay_of(bag, topic: str, tick_ns: int):
    """The external inputs a run recorded, as a replay (tick -> {topic: message})."""
    with BagReader(bag) as reader:
        recorded = {stamp // tick_ns: msg for stamp, msg in reader.messages(topic)}
    return lambda tick: {topic: recorded[tick]} if tick in recorded else {}


def test_roslibjs_and_roslibpy_drive_a_lockstep_run_that_replays(tmp_path):
    scenario = drive_scenario(tmp_path, duration="4s")
    port = free_port()
    orch = orchestrate(scenario, tmp_path / "runs", "--paused", "--rosbridge", f"127.0.0.1:{port}")
    wait_listening(port, orch)
    # a second client at once: roslibpy, throttled to one scan per 500 ms
    ros = roslibpy_client(port)
    throttled = []
    roslibpy.Topic(ros, "/scan", "sensor_msgs/LaserScan", throttle_rate=500,
                   queue_length=1).subscribe(lambda _msg: throttled.append(time.monotonic()))
    # a round trip on the same connection: the subscription is in place before the run goes on
    paused = roslibpy.Service(ros, "/cosim/pause", "std_srvs/SetBool").call(
        roslibpy.ServiceRequest({"data": True}), timeout=60)
    assert paused["success"] and paused["message"].startswith("paused at tick 0"), paused
    started = time.monotonic()
    js = node_client("rosbridge_client.mjs", f"ws://127.0.0.1:{port}", "--topics",
                     "/odom,/scan", "--cbor", "/scan", "--cmd-vel", "0.5")
    got = summary(js)
    code, _, err = finish(orch)
    ros.close()
    took = time.monotonic() - started
    assert code == 0, err
    assert got["errors"] == []
    assert got["step"] == {"success": True,
                           "message": "stepping one tick; paused at tick 0 (sim time "
                                      "0.000000000 s)"}
    assert got["resume"]["success"] and got["resume"]["message"].startswith("running at tick")
    odom, scan = got["topics"]["/odom"], got["topics"]["/scan"]
    assert odom["count"] > 100 and odom["first"] == {"stamp": 0, "x": -3.0}
    assert odom["last"]["stamp"] == 4_000_000_000
    assert odom["last"]["x"] > -3.0 + 0.5  # it drove: /cmd_vel entered the run
    assert scan["count"] > 20 and scan["last"]["ranges"] == 360  # these came as CBOR
    # at most one scan per 500 ms of wall time (a fast run may give only one)
    # at most one scan per 500 ms of the time the run took, however long that was (a ratio:
    # the times the client saw them at bunch up when it is slow to read)
    assert 1 <= len(throttled) < scan["count"]
    assert len(throttled) <= took / 0.5 + 2
    live = manifest(tmp_path / "runs")["live"]["rosbridge"]
    assert live["clients"] == 2 and live["clients_at_once"] == 2
    assert live["published_by_clients"] >= 1 and live["errors"] == 0
    # what the clients sent is in the bag, at ticks: replayed in-process, the same run
    loaded = load(scenario)
    first = manifest(tmp_path / "runs")
    with BagReader(run_dir(tmp_path / "runs") / "bag") as bag:
        speeds = [msg.linear.x for _, msg in bag.messages("/cmd_vel")]
    assert speeds[0] == 0.0 and speeds[-1] == 0.5
    replayed = run(loaded, in_process=True, out=tmp_path / "replay",
                   external=replay_of(run_dir(tmp_path / "runs") / "bag", "/cmd_vel",
                                      loaded.tick_ns), picture=False)
    assert replayed.digest == first["digest"]
    # --replay from the run directory alone: the client publishes recorded as they arrived
    again = api.replay(run_dir(tmp_path / "runs"), in_process=True, out=tmp_path / "again")
    assert again.digest == first["digest"]


@pytest.fixture
def realtime_physics():
    """A standalone realtime physics node with rosbridge (and Foxglove) on free ports."""
    port, live = free_port(), free_port()
    proc = cosim_node("physics", "--scenario", str(NAV), "--realtime", "--rosbridge",
                      f"127.0.0.1:{port}", "--live", f"127.0.0.1:{live}")
    try:
        wait_listening(port, proc)
        wait_listening(live, proc)
        yield SimpleNamespace(rosbridge=port, live=live)
    finally:
        proc.send_signal(signal.SIGINT)
        code, _, err = finish(proc, timeout=30)
        assert code == 0, err


def stamp_ns(msg: dict) -> int:
    """A rosbridge message's header stamp in nanoseconds."""
    stamp = msg["header"]["stamp"]
    return stamp["sec"] * 10**9 + stamp["nanosec"]


def until(condition, what: str, timeout: float = HANG_S) -> None:
    """Wait for ``condition()``; fail naming ``what`` after ``timeout`` (a hang guard)."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.02)


def paused_at_ns(message: str) -> int:
    """The sim time of 'paused at tick 12 (sim time 0.240000000 s)', in nanoseconds."""
    found = re.search(r"paused at tick \d+ \(sim time (\d+)\.(\d{9}) s\)", message)
    assert found, message
    return int(found.group(1)) * 10**9 + int(found.group(2))


def test_roslibpy_drives_pauses_and_steps_a_realtime_physics_node(realtime_physics):
    ros = roslibpy_client(realtime_physics.rosbridge)
    try:
        odoms = []
        roslibpy.Topic(ros, "/odom", "nav_msgs/Odometry").subscribe(odoms.append)
        cmd = roslibpy.Topic(ros, "/cmd_vel", "geometry_msgs/Twist")
        cmd.advertise()

        def x() -> list[float]:
            return [m["pose"]["pose"]["position"]["x"] for m in list(odoms)]

        deadline = time.monotonic() + HANG_S
        while not (len(odoms) > 30 and x()[-1] > x()[0] + 0.1):
            assert time.monotonic() < deadline, "the robot did not move"
            cmd.publish(roslibpy.Message({"linear": {"x": 0.5}}))
            time.sleep(0.1)
        pause = roslibpy.Service(ros, "/cosim/pause", "std_srvs/SetBool")
        step = roslibpy.Service(ros, "/cosim/step", "std_srvs/srv/Trigger")
        answer = pause.call(roslibpy.ServiceRequest({"data": True}), timeout=10)
        assert answer["success"] and answer["message"].startswith("paused at tick")
        # the last tick that ran is the one the answer names: wait for its /odom to arrive
        last = paused_at_ns(answer["message"])
        until(lambda: any(stamp_ns(m) == last for m in list(odoms)), "the last tick's /odom")
        held = next(i for i, m in enumerate(odoms) if stamp_ns(m) == last) + 1
        time.sleep(0.3)  # a window in which a node that went on would publish ~15 more
        assert len(odoms) == held, "a paused node went on"
        answer = step.call(roslibpy.ServiceRequest(), timeout=10)
        assert answer["success"] and answer["message"].startswith("stepping one tick")
        until(lambda: len(odoms) > held, "the stepped tick's /odom")
        assert stamp_ns(odoms[held]) - last == 20_000_000  # exactly the next tick
        time.sleep(0.3)  # again: one step is one tick
        assert len(odoms) == held + 1
        assert pause.call(roslibpy.ServiceRequest({"data": False}), timeout=10)["success"]
        until(lambda: len(odoms) > held + 5, "/odom after resuming")
        topics = ros.get_topics()
        assert {"/odom", "/cmd_vel", "/clock", "/tf_static"} <= set(topics)
        # /tf_static went out once, seconds ago: a late subscriber still gets it (latched)
        static = []
        roslibpy.Topic(ros, "/tf_static", "tf2_msgs/msg/TFMessage").subscribe(static.append)
        until(lambda: static, "the latched /tf_static")
        assert len(static) == 1 and static[0]["transforms"]
    finally:
        ros.close()


def test_a_late_foxglove_client_of_a_realtime_node_gets_tf_static(realtime_physics):
    """/tf_static went out at the node's first step; Foxglove's client, subscribing a second
    later, still gets it (and /odom as it comes)."""
    ros = roslibpy_client(realtime_physics.rosbridge)
    try:  # wait until the node has stepped (so /tf_static has gone out) and then some
        odoms = []
        roslibpy.Topic(ros, "/odom", "nav_msgs/Odometry").subscribe(odoms.append)
        until(lambda: odoms and stamp_ns(odoms[-1]) >= 500_000_000, "the node to run 0.5 s")
    finally:
        ros.close()
    got = summary(node_client("foxglove_client.mjs", f"ws://127.0.0.1:{realtime_physics.live}",
                              "--topics",
                              "/tf_static,/odom", "--drive", "no", "--seconds", "2"))
    assert got["topics"]["/tf_static"]["count"] == 1
    assert got["topics"]["/tf_static"]["first"]["transforms"]
    assert got["topics"]["/odom"]["count"] > 20


def ops(ws, *frames, want: int) -> list[dict]:
    """Send frames; return the next ``want`` replies (JSON) that are not publish ops."""
    for frame in frames:
        ws.send(frame)
    out = []
    while len(out) < want:
        reply = json.loads(ws.recv(timeout=10))
        if reply["op"] != "publish":
            out.append(reply)
    return out


def test_bad_frames_get_an_error_status_and_the_connection_stays(realtime_physics):
    with connect(f"ws://127.0.0.1:{realtime_physics.rosbridge}", max_size=None) as ws:
        replies = ops(
            ws,
            "{not json",
            "[1, 2]",
            json.dumps({"op": "frobnicate", "id": "f1"}),
            json.dumps({"op": "publish", "id": "p1", "topic": "/cmd_vel",
                        "msg": {"linear": {"x": "fast"}}}),
            json.dumps({"op": "publish", "id": "p2", "topic": "/cmd_vel",
                        "msg": {"linear": {"speed": 1}}}),
            json.dumps({"op": "publish", "id": "p3", "topic": "/odom", "msg": {}}),
            json.dumps({"op": "advertise", "id": "a1", "topic": "/cmd_vel",
                        "type": "std_msgs/String"}),
            json.dumps({"op": "subscribe", "id": "s1", "topic": "/odom",
                        "type": "sensor_msgs/msg/Image"}),
            json.dumps({"op": "subscribe", "id": "s2", "topic": "/nothing"}),
            json.dumps({"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": 0}},
                        "pad": "x" * (9 * 2**20)}),
            want=10)
        assert all(r["op"] == "status" and r["level"] == "error" for r in replies), replies
        texts = [r["msg"] for r in replies]
        assert "malformed JSON" in texts[0]
        assert "JSON object with an 'op'" in texts[1]
        assert "unknown op 'frobnicate'" in texts[2] and replies[2]["id"] == "f1"
        assert "linear.x: expected a number, got a string" in texts[3]
        assert "has no field 'speed'" in texts[4]
        assert "/odom is not an input of node physics; it takes /cmd_vel" in texts[5]
        assert "takes geometry_msgs/msg/Twist, not std_msgs/String" in texts[6]
        assert "/odom is nav_msgs/msg/Odometry, not sensor_msgs/msg/Image" in texts[7]
        assert "no topic /nothing" in texts[8]
        assert "over the 8388608 byte limit" in texts[9]
        # unknown service: a failed service_response, and the status
        replies = ops(ws, json.dumps({"op": "call_service", "id": "c1",
                                      "service": "/cosim/warp"}), want=2)
        response = next(r for r in replies if r["op"] == "service_response")
        assert response["result"] is False and "no service /cosim/warp" in response["values"]
        # and the connection still serves
        ws.send(json.dumps({"op": "subscribe", "topic": "/odom", "type": "nav_msgs/Odometry"}))
        message = json.loads(ws.recv(timeout=10))
        assert message["op"] == "publish" and message["topic"] == "/odom"
        assert message["msg"]["header"]["frame_id"] == "odom"


def test_a_taken_port_is_bad_input_and_nothing_starts(tmp_path):
    from tests.helpers import orchestrate as orchestrate_cli

    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        port = held.getsockname()[1]
        result = orchestrate_cli(NAV, tmp_path, "--rosbridge", f"127.0.0.1:{port}", timeout=60)
    assert result.code == 2 and result.run_dir is None
    assert f"--rosbridge 127.0.0.1:{port}: cannot listen there" in result.stderr


def test_a_navigate_to_pose_goal_over_rosbridge(tmp_path):
    """roslibjs-style send_action_goal to the run's NavigateToPose, with feedback (Nav2's
    estimate of the time left included), then play: the goal succeeds."""
    import math

    from tests.live_helpers import nav_doc, write

    doc = nav_doc("30s")
    doc["interactive"] = True
    doc["success"]["stop_on_goal"] = False
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] != "camera"]
    scenario = write(tmp_path, doc, "nav_interactive")
    port = free_port()
    orch = orchestrate(scenario, tmp_path / "runs", "--paused", "--rosbridge",
                       f"127.0.0.1:{port}")
    try:
        wait_listening(port, orch)
        with connect(f"ws://127.0.0.1:{port}", max_size=None) as ws:
            yaw = 0.785  # 1 m straight ahead of the start (-3, -3)
            ws.send(json.dumps({
                "op": "send_action_goal", "id": "nav1", "action": "/navigate_to_pose",
                "action_type": "nav2_msgs/NavigateToPose", "feedback": True,
                "args": {"pose": {"header": {"frame_id": "map"}, "pose": {
                    "position": {"x": -2.3, "y": -2.3},
                    "orientation": {"z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}}}}}))
            ws.send(json.dumps({"op": "call_service", "id": "play",
                                "service": "/set_simulation_state",
                                "args": {"state": {"state": 1}}}))  # STATE_PLAYING
            feedback, replies = [], []
            while True:
                reply = json.loads(ws.recv(timeout=120))
                if reply["op"] == "action_feedback":
                    feedback.append(reply["values"])
                elif reply["op"] == "action_result":
                    break
                else:
                    replies.append(reply)
            ws.send(json.dumps({"op": "call_service", "service": "/set_simulation_state",
                                "args": {"state": {"state": 0}}}))  # STATE_STOPPED
            code, _, err = finish(orch)
    finally:
        if orch.poll() is None:
            orch.terminate()
            finish(orch)
    assert reply["id"] == "nav1" and reply["status"] == 4 and reply["result"] is True, reply
    assert reply["values"]["error_code"] == 0
    played = next(r for r in replies if r.get("id") == "play")
    assert played["result"] is True and played["values"]["result"]["result"] == 1, played
    assert len(feedback) > 5
    assert feedback[0]["distance_remaining"] > 0.8 > 0.3 > feedback[-1]["distance_remaining"]
    assert any(f["estimated_time_remaining"]["sec"] > 0 for f in feedback), feedback
    assert code == 0, err  # stopped by the client, the control node's goal reached
