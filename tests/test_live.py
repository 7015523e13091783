"""The Foxglove live view (--live) with Foxglove's own client (@foxglove/ws-protocol, under
node): it subscribes, decodes the CDR with the advertised ros2msg schemas, follows sim time
and steps and resumes the run through the services; the digest is the one of a run without
--live; stuck clients never slow the run nor grow its memory; and the small parts (schemas,
JSON conversion, bounded queues, addresses) on their own."""

from __future__ import annotations

import json
import math

import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Image, LaserScan
from std_srvs.srv import SetBool

from orchestrator.api import load, run
from orchestrator.run_rules import check_run
from plan.listen import parse_listen
from plan.options import RunOptions
from runtime.live.channels import BoundedChannels
from runtime.live.convert import MessageError, from_json, to_json
from runtime.live.schemas import message_schema, service_schemas
from tests.live_helpers import (
    finish,
    free_port,
    manifest,
    nav_doc,
    node_client,
    orchestrate,
    summary,
    wait_listening,
    write,
)

CAMERA = "/camera/color/image_raw"
DEPTH = "/camera/depth/image_rect"


def test_foxglove_client_follows_nav_and_the_digest_is_unchanged(tmp_path):
    scenario = write(tmp_path, nav_doc("3s"), "nav3")
    topics = ["/odom", CAMERA, "/clock", "/tf", "/tf_static"]
    port = free_port()
    orch = orchestrate(scenario, tmp_path / "runs", "--paused", "--live", f"127.0.0.1:{port}")
    wait_listening(port, orch)
    got = summary(node_client("foxglove_client.mjs", f"ws://127.0.0.1:{port}", "--topics",
                              ",".join(topics)))
    code, _, err = finish(orch)
    assert code in (0, 1), err  # 3 s does not reach nav's goal
    # every wanted channel was advertised as CDR with its ros2msg schema, and decoded
    assert got["schemas"]["/odom"] == ["cdr", "ros2msg", "nav_msgs/msg/Odometry"]
    assert got["schemas"][CAMERA] == ["cdr", "ros2msg", "sensor_msgs/msg/Image"]
    assert set(got["topics"]) == set(topics)
    odom, image = got["topics"]["/odom"], got["topics"][CAMERA]
    assert odom["first"]["frame_id"] == "odom" and odom["first"]["x"] == -3.0
    assert odom["last"]["stamp"] == odom["last"]["log_time"] == 3_000_000_000
    assert image["last"] == {"log_time": 3_000_000_000, "frame_id": image["last"]["frame_id"],
                             "stamp": 3_000_000_000, "width": 160, "height": 120,
                             "encoding": "rgb8", "bytes": 160 * 120 * 3}
    assert "base_link" in got["topics"]["/tf"]["last"]["transforms"]
    assert got["topics"]["/tf_static"]["count"] >= 1
    assert got["topics"]["/tf_static"]["first"]["transforms"]
    # sim time is the server's time; the services stepped once, then resumed the run
    assert got["times"] > 2 and got["first_time"] < got["last_time"] == 3_000_000_000
    assert {"/cosim/pause", "/cosim/step", "/cosim/reset"} <= {n for n, _ in got["services"]}
    assert got["step"] == {"success": True, "message": "stepping one tick; paused at tick 0 "
                                                       "(sim time 0.000000000 s)"}
    assert got["resume"]["success"] and got["resume"]["message"].startswith("running at tick")
    assert not [e for e in got["errors"] if "opcode" not in e]  # 5: playback state, newer
    live = manifest(tmp_path / "runs")
    assert live["live"]["foxglove"]["clients"] == 1
    reference = run(scenario, in_process=True, out=tmp_path / "reference", picture=False)
    assert live["digest"] == reference.digest


def stuck_rosbridge_client(port: int):
    """A rosbridge client that subscribes to both camera images and never reads again."""
    import socket

    from websockets.sync.client import connect

    # A small receive buffer: the kernel holds little of what the client does not read, so
    # the server's queue fills however fast the machine drains the socket (a loaded machine
    # absorbed a whole run's images in its buffers once: nothing dropped)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    ws = connect(f"ws://127.0.0.1:{port}", sock=sock, max_queue=1)
    for topic in (CAMERA, DEPTH):
        ws.send(json.dumps({"op": "subscribe", "topic": topic}))
    return ws


def test_three_image_clients_one_stuck_change_nothing(tmp_path):
    doc = nav_doc("6s")
    camera = next(n for n in doc["nodes"] if n["name"] == "camera")
    camera["rate"] = 25
    scenario = write(tmp_path, doc, "nav_images")
    live, bridge = free_port(), free_port()
    orch = orchestrate(scenario, tmp_path / "runs", "--paused", "--live", f"127.0.0.1:{live}",
                       "--rosbridge", f"127.0.0.1:{bridge}")
    wait_listening(live, orch)
    wait_listening(bridge, orch)
    stuck_bridge = stuck_rosbridge_client(bridge)
    images = ",".join([CAMERA, DEPTH])
    stuck = node_client("foxglove_client.mjs", f"ws://127.0.0.1:{live}", "--topics", images,
                        "--drive", "no", "--stall", "--seconds", "120")
    reader = node_client("foxglove_client.mjs", f"ws://127.0.0.1:{live}", "--topics", images)
    got = summary(reader, timeout=180)
    code, _, err = finish(orch, timeout=180)
    stuck.kill()
    finish(stuck)
    stuck_bridge.close()
    assert code in (0, 1), err
    assert got["topics"][CAMERA]["count"] > 75 and got["topics"][DEPTH]["count"] > 75
    ran = manifest(tmp_path / "runs")
    assert ran["live"]["foxglove"]["clients_at_once"] == 2
    assert ran["live"]["rosbridge"]["clients"] == 1
    # the stuck rosbridge client lost its oldest images instead of holding them all
    assert ran["live"]["rosbridge"]["dropped"].get(CAMERA, 0) > 0
    # a gross leak guard only: the drops counted above are what show the queues are bounded.
    # The peak depends on the machine's load (245 MB alone on a 2-core machine, 779 MB with the
    # test suite's two workers and other jobs beside it: the clients' threads and buffers)
    assert ran["orchestrator"]["peak_rss_mb"] < 1500
    reference = run(scenario, in_process=True, out=tmp_path / "reference", picture=False)
    assert ran["digest"] == reference.digest


# -- the parts on their own ----------------------------------------------------------------


def test_schemas_are_ros2msg_text_with_dependencies():
    text = message_schema("nav_msgs/Odometry")
    assert text.startswith("std_msgs/Header header\nstring child_frame_id\n")
    assert "\n" + "=" * 80 + "\nMSG: geometry_msgs/PoseWithCovariance\n" in text
    # a package rosbags does not know, read from the venv's share/
    assert "MSG: simulation_interfaces/Result" in service_schemas(
        "simulation_interfaces/srv/StepSimulation")[1]
    assert service_schemas("std_srvs/srv/SetBool") == ("bool data\n",
                                                       "bool success\nstring message\n")


def test_json_follows_rosbridge_rules():
    scan = LaserScan(ranges=[1.0, math.inf, math.nan])
    assert to_json(scan)["ranges"] == [1.0, None, None]  # JSON has no inf/NaN
    assert to_json(scan, binary=True)["ranges"][1] == math.inf  # CBOR has
    image = Image(height=1, width=3, data=bytes([1, 2, 255]))
    assert to_json(image)["data"] == "AQL/"  # uint8[] as base64
    assert from_json(Image, to_json(image)).data.tobytes() == bytes([1, 2, 255])
    odom = Odometry()
    odom.pose.covariance[35] = 2.5
    back = from_json(Odometry, json.loads(json.dumps(to_json(odom))))
    assert back.pose.covariance[35] == 2.5
    assert from_json(Twist, {"linear": {"x": 1}}).linear.x == 1.0  # an int is a float
    with pytest.raises(MessageError, match=r"Twist.angular \(geometry_msgs/msg/Vector3\) has "
                                           r"no field 'w'"):
        from_json(Twist, {"angular": {"w": 1.0}})
    with pytest.raises(MessageError, match="SetBool_Request.data: expected true or false"):
        from_json(SetBool.Request, {"data": 1}, "std_srvs/srv/SetBool_Request")


def test_bounded_channels_drop_the_oldest_and_count():
    woken = []
    queue = BoundedChannels(3, on_first=lambda: woken.append(1))
    for i in range(5):
        queue.put("/a", i)
    queue.put("/b", "x")
    assert queue.take() == [("/a", 2), ("/a", 3), ("/a", 4), ("/b", "x")]
    assert queue.dropped == {"/a": 2} and queue.dropped_total() == 2
    assert woken == [1]  # once per batch: the consumer is woken when the first one comes
    queue.put("/a", 9)
    assert woken == [1, 1] and queue.take(timeout_s=0.01) == [("/a", 9)]
    assert queue.take(timeout_s=0.01) == []


def test_addresses_loopback_by_default_and_a_warning_otherwise(tmp_path):
    assert str(parse_listen("", "127.0.0.1:9090")) == "127.0.0.1:9090"
    assert str(parse_listen("9100", "127.0.0.1:9090")) == "127.0.0.1:9100"
    assert str(parse_listen("[::1]:9100", "127.0.0.1:9090")) == "[::1]:9100"
    with pytest.raises(ValueError, match="not an IP address"):
        RunOptions(rosbridge="example.org:9090")
    with pytest.raises(ValueError, match="port must be a number"):
        RunOptions(live="127.0.0.1:99999")
    scenario = load(write(tmp_path, nav_doc("1s"), "nav1"))
    assert not [w for w in check_run(scenario, RunOptions(live="127.0.0.1:0"))
                if "authentication" in w]
    warnings = check_run(scenario, RunOptions(rosbridge="0.0.0.0:0"))
    assert any("rosbridge (--rosbridge) listens on 0.0.0.0:0, reachable from other machines, "
               "and has no authentication" in w for w in warnings)


def test_in_process_runs_serve_clients_too(tmp_path):
    """An in-process run offers what its observer sees (and /clock it makes up)."""
    from websockets.sync.client import connect

    scenario = write(tmp_path, nav_doc("20s"), "nav20")
    port = free_port()
    orch = orchestrate(scenario, tmp_path / "runs", "--in-process", "--rosbridge",
                       f"127.0.0.1:{port}")
    wait_listening(port, orch)
    seen = set()
    with connect(f"ws://127.0.0.1:{port}") as ws:
        for topic in ("/odom", "/clock"):
            ws.send(json.dumps({"op": "subscribe", "topic": topic}))
        while len(seen) < 2:
            seen.add(json.loads(ws.recv(timeout=30))["topic"])
    code, _, err = finish(orch)
    assert code in (0, 1), err
    assert seen == {"/odom", "/clock"}
