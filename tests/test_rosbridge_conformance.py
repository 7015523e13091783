"""rosbridge_suite's own websocket test cases (rosbridge_server/test/websocket/), run against
cosim's rosbridge server on a lockstep run and on a standalone realtime node.

Each case sends the frames the upstream case sends and expects what it expects. Upstream, the
ROS side of a case is the test's own node (a publisher, a subscriber, a service, an action
server); here it is the simulation's: tests/scenarios/rosbridge_conformance.yaml's chatter
node publishes the cases' std_msgs/String messages ("BBBBBBBBBB" on /b_topic; "hello" on
/hello_topic every activation and on /latched_topic once, latched, where the cases publish
"hello" on /a_topic), /a_topic is the run's input from outside, the service is the run's
std_srvs/SetBool /cosim/pause, and the action is simulation_interfaces' SimulateSteps. Where
upstream's ROS node publishes N messages, the run is stepped N ticks (a realtime node
publishes on its own). The cases left out, and the differences, are listed in docs/how-to/live.md
("rosbridge conformance").
"""

from __future__ import annotations

import json
import signal
import time

import cbor2
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from simulation_interfaces.msg import Result, SimulationState
from std_msgs.msg import String
from websockets.sync.client import connect

from tests.helpers import SCENARIOS
from tests.live_helpers import cosim_node, finish, free_port, orchestrate, wait_listening
from tests.sim_client import SimClient

SCENARIO = SCENARIOS / "rosbridge_conformance.yaml"
NUM_MSGS, MSG_SIZE = 10, 10  # smoke
A_STRING, B_STRING = "A" * MSG_SIZE, "B" * MSG_SIZE
HELLO = {"op": "publish", "topic": "/hello_topic", "msg": {"data": "hello"}}
LATCHED = {"op": "publish", "topic": "/latched_topic", "msg": {"data": "hello"}}
STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_UNKNOWN = 4, 5, 0  # action_msgs/GoalStatus
RECV_S = 20


class Client:
    """A websocket client as upstream's test client is: JSON text frames out, frames in."""

    def __init__(self, port: int):
        self.ws = connect(f"ws://127.0.0.1:{port}", max_size=None).__enter__()

    def send_json(self, payload: dict, times: int = 1) -> None:
        for _ in range(times):
            self.ws.send(json.dumps(payload))

    def expect_messages(self, n: int) -> list:
        """The next ``n`` frames (JSON decoded; binary frames CBOR decoded)."""
        out = []
        for _ in range(n):
            frame = self.ws.recv(timeout=RECV_S)
            out.append(cbor2.loads(frame) if isinstance(frame, bytes) else json.loads(frame))
        return out

    def close(self) -> None:
        self.ws.close()


def subscribe(topic: str, **extra) -> dict:
    return {"op": "subscribe", "topic": topic, "type": "std_msgs/String", **extra}


# -- the cases: ``tick(n)`` makes the simulation publish n more times -------------------------


def smoke(port: int, tick) -> None:
    """smoke.test.py: subscribe (queue_length 0, roslib's default) and advertise, publish
    NUM_MSGS, receive NUM_MSGS on both sides."""
    ws = Client(port)
    ws.send_json(subscribe("/b_topic", queue_length=0))
    ws.send_json({"op": "advertise", "topic": "/a_topic", "type": "std_msgs/String"})
    time.sleep(1.0)  # WARMUP_DELAY
    ws.send_json({"op": "publish", "topic": "/a_topic", "msg": {"data": A_STRING}},
                 times=NUM_MSGS)
    tick(NUM_MSGS)
    ws_received = ws.expect_messages(NUM_MSGS)
    for msg in ws_received:
        assert msg["op"] == "publish", msg
        assert msg["topic"] == "/b_topic" and msg["msg"]["data"] == B_STRING, msg
    assert len(ws_received) == NUM_MSGS
    ws.close()


def call_service(port: int) -> None:
    """call_service.test.py: one call of a std_srvs/SetBool service with data true."""
    ws = Client(port)
    ws.send_json({"op": "call_service", "type": "std_srvs/SetBool", "service": "/cosim/pause",
                  "args": {"data": True}})
    (response,) = ws.expect_messages(1)
    assert response["op"] == "service_response", response
    assert response["service"] == "/cosim/pause"
    assert response["values"]["success"] is True, response  # upstream: its own server's text
    assert response["values"]["message"].startswith("paused at tick"), response
    assert response["result"] is True
    ws.close()


def best_effort_publisher(port: int, tick) -> None:
    """best_effort_publisher.test.py: subscribe, the publisher sends one message."""
    ws = Client(port)
    ws.send_json(subscribe("/hello_topic"))
    time.sleep(1.0)
    tick(1)
    assert ws.expect_messages(1) == [HELLO]
    ws.close()


def multiple_subscribers(port: int, tick, compression: str | None = None) -> None:
    """multiple_subscribers(_raw).test.py: two clients subscribe, both receive it."""
    extra = {"compression": compression} if compression else {}
    clients = [Client(port), Client(port)]
    for ws in clients:
        ws.send_json(subscribe("/hello_topic", **extra))
    time.sleep(1.0)
    tick(1)
    for ws in clients:
        got = ws.expect_messages(1)
        if compression == "cbor-raw":  # upstream: truthy; here: the CDR bytes of "hello"
            assert got[0]["op"] == "publish" and got[0]["topic"] == "/hello_topic"
            assert got[0]["msg"]["bytes"] == serialize_message(String(data="hello"))
        else:
            assert got == [HELLO]
        ws.close()


def transient_local_publisher(port: int) -> None:
    """transient_local_publisher.test.py: published once, long ago; three clients in turn
    each receive it."""
    time.sleep(1.0)
    for _ in range(3):
        ws = Client(port)
        ws.send_json(subscribe("/latched_topic"))
        assert ws.expect_messages(1) == [LATCHED]
        ws.close()


def send_action_goal(port: int) -> None:
    """send_action_goal.test.py: a goal with feedback: each feedback, then the result."""
    ws = Client(port)
    ws.send_json({"op": "send_action_goal", "action": "/simulate_steps",
                  "action_type": "simulation_interfaces/SimulateSteps", "args": {"steps": 5},
                  "feedback": True})
    responses = ws.expect_messages(6)
    for i in range(5):
        assert responses[i]["op"] == "action_feedback", responses
        assert responses[i]["values"] == {"completed_steps": i + 1, "remaining_steps": 4 - i}
    assert responses[-1]["op"] == "action_result"
    assert responses[-1]["action"] == "/simulate_steps"
    assert responses[-1]["values"]["result"]["result"] == Result.RESULT_OK
    assert responses[-1]["status"] == STATUS_SUCCEEDED
    assert responses[-1]["result"] is True
    # and cancel_action_goal, by the goal's id: no step after it, the result says cancelled
    ws.send_json({"op": "send_action_goal", "id": "g1", "action": "/simulate_steps",
                  "action_type": "simulation_interfaces/SimulateSteps",
                  "args": {"steps": 100_000}, "feedback": True})
    assert ws.expect_messages(3)[-1]["op"] == "action_feedback"
    ws.send_json({"op": "cancel_action_goal", "id": "g1", "action": "/simulate_steps"})
    while (reply := ws.expect_messages(1)[0])["op"] == "action_feedback":
        assert reply["id"] == "g1"
    assert reply["op"] == "action_result" and reply["id"] == "g1", reply
    assert reply["status"] == STATUS_CANCELED and reply["result"] is True, reply
    ws.close()


# -- the two servers --------------------------------------------------------------------------


def test_cases_on_a_lockstep_run(tmp_path, ros_node):
    sim = SimClient(ros_node)
    port = free_port()
    received: list = []
    node, _ = ros_node
    listener = node.create_subscription(
        String, "/a_topic", received.append,
        QoSProfile(depth=NUM_MSGS, reliability=ReliabilityPolicy.RELIABLE))
    run = orchestrate(SCENARIO, tmp_path, "--paused", "--rosbridge", f"127.0.0.1:{port}")
    try:
        wait_listening(port, run)
        assert sim.state() == SimulationState.STATE_PAUSED  # the services are up
        # the run's /a_topic publisher and this subscriber find each other before anything is
        # published (a volatile subscriber gets nothing sent before that: on a loaded machine
        # discovery outlasted the case's warm-up)
        sim.spin_until(lambda: listener.get_publisher_count() > 0)
        sim.spin(0.5)

        def tick(n: int) -> None:
            assert sim.step(n).result == Result.RESULT_OK

        smoke(port, tick)
        sim.spin_until(lambda: len(received) >= NUM_MSGS)
        smoke_ros = list(received)
        assert [m.data for m in smoke_ros] == [A_STRING] * NUM_MSGS  # the ROS side of smoke
        call_service(port)
        best_effort_publisher(port, tick)
        multiple_subscribers(port, tick)
        multiple_subscribers(port, tick, "cbor-raw")
        transient_local_publisher(port)
        send_action_goal(port)
        ws = Client(port)  # roslibjs' getActionServers
        ws.send_json({"op": "call_service", "service": "/rosapi/action_servers", "args": {}})
        assert ws.expect_messages(1)[0]["values"] == {"action_servers": ["/simulate_steps"]}
        ws.close()
        assert sim.set_state(SimulationState.STATE_STOPPED).result == Result.RESULT_OK
        code, _, err = finish(run)
    finally:
        if run.poll() is None:
            run.terminate()
            finish(run)
    assert code == 0, err


def test_cases_on_a_realtime_node():
    port = free_port()
    proc = cosim_node("any", "--scenario", str(SCENARIO), "--node", "chatter", "--realtime",
                      "--rosbridge", f"127.0.0.1:{port}")
    try:
        wait_listening(port, proc)

        def tick(_n: int) -> None:
            """A realtime node publishes at its rate on its own."""

        smoke(port, tick)  # its /a_topic goes to the node's input, not the ROS graph
        call_service(port)  # pauses it
        ws = Client(port)
        ws.send_json({"op": "call_service", "service": "/cosim/pause", "args": {"data": False}})
        assert ws.expect_messages(1)[0]["values"]["success"] is True
        ws.close()
        best_effort_publisher(port, tick)
        multiple_subscribers(port, tick)
        multiple_subscribers(port, tick, "cbor-raw")
        transient_local_publisher(port)
        # send_action_goal: a standalone node has no action server; rosbridge's answer to a
        # goal it cannot send: a failed action_result (and an error status)
        ws = Client(port)
        ws.send_json({"op": "send_action_goal", "action": "/simulate_steps",
                      "action_type": "simulation_interfaces/SimulateSteps",
                      "args": {"steps": 5}, "feedback": True})
        replies = ws.expect_messages(2)
        result = next(r for r in replies if r["op"] == "action_result")
        assert result["result"] is False and result["status"] == STATUS_UNKNOWN
        assert "no action /simulate_steps" in result["values"]
        ws.close()
    finally:
        proc.send_signal(signal.SIGINT)
        code, _, err = finish(proc, timeout=30)
    assert code == 0, err
