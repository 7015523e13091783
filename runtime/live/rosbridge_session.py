"""One rosbridge client connection: its subscriptions, its advertised topics, its ops.

Messages for the client wait in one bounded queue per subscribed topic (the newest
``queue_length`` of them, oldest dropped and counted) and a single writer task sends them,
honouring each subscription's ``throttle_rate``; a client that stops reading only ever
blocks its own writer. Replies (status, service responses) go first, through a bounded queue
of their own; a client that lets even those pile up is disconnected.
"""

from __future__ import annotations

import asyncio
import json
import logging
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from plan.ros_types import ros_type
from runtime.live import convert
from runtime.live.endpoints import ServiceUnavailable
from runtime.live.schemas import normalise_type, same_type

log = logging.getLogger("cosim")

LEVELS = {"info": 0, "warning": 1, "error": 2, "none": 3}
DEFAULT_QUEUE = 32  # messages kept per topic when a subscription asks for no queue (0)
MAX_QUEUE = 1000
MAX_REPLIES = 1000
COMPRESSIONS = ("none", "cbor", "cbor-raw")
SERVICE_TIMEOUT_S = 10.0
OPS = ("subscribe", "unsubscribe", "advertise", "unadvertise", "publish", "call_service",
       "set_level", "send_action_goal", "cancel_action_goal")
STATUS_UNKNOWN = 0  # action_msgs/GoalStatus: what rosbridge reports for a goal that failed
NOT_SERVED = {  # rosbridge ops this server refuses, and why
    **dict.fromkeys(("advertise_service", "unadvertise_service", "service_response",
                     "advertise_action", "unadvertise_action", "action_feedback",
                     "action_result"),
                    "a simulation's endpoint serves the run's own services and actions; it "
                    "hosts none of a client's (run a ROS 2 node for those)"),
    "fragment": "fragmented messages are not taken (frames up to 8 MiB are)",
}


class ClientError(Exception):
    """An op that cannot be served: answered with an error status, the connection stays."""


@dataclass
class Subscription:
    """One client's subscription to a topic (several subscribe ops merged, as rosbridge
    does: the lowest throttle, the longest queue)."""

    topic: str
    ids: dict[str | None, tuple[int, int, str]] = field(default_factory=dict)
    queue: deque = field(default_factory=lambda: deque(maxlen=DEFAULT_QUEUE))
    throttle_s: float = 0.0
    compression: str = "none"
    next_at: float = 0.0
    dropped: int = 0

    def merge(self) -> None:
        """Recompute throttle, queue length and compression from the ids."""
        throttles = [t for t, _, _ in self.ids.values()]
        lengths = [q for _, q, _ in self.ids.values()]
        self.throttle_s = min(throttles) / 1000.0
        depth = max(lengths)
        depth = min(depth, MAX_QUEUE) if depth > 0 else DEFAULT_QUEUE
        if depth != self.queue.maxlen:
            self.queue = deque(self.queue, maxlen=depth)
        self.compression = next(iter(self.ids.values()))[2]

    def push(self, message: Any) -> None:
        """Queue a message (a rosbridge.OutgoingMessage); the oldest goes when full."""
        if len(self.queue) == self.queue.maxlen:
            self.dropped += 1
        self.queue.append(message)


class ClientSession:
    """Serves one websocket connection until it closes."""

    def __init__(self, server: Any, websocket, number: int):
        """``server``: the RosbridgeServer this connection belongs to."""
        self.server = server
        self.ws = websocket
        self.number = number
        self.level = LEVELS["error"]
        self.subs: dict[str, Subscription] = {}
        self.advertised: set[str] = set()
        self.replies: deque = deque()
        self.goals: dict[Any, threading.Event] = {}  # op id -> its cancel request
        self.wake = asyncio.Event()
        self.closed = False

    # -- the connection's two tasks -------------------------------------------------------

    async def serve(self) -> None:
        """Read ops until the client leaves; a writer task sends in the meantime."""
        writer = asyncio.create_task(self._write())
        try:
            async for frame in self.ws:
                self._handle(frame)
        except Exception as exc:  # noqa: BLE001 - a broken connection ends only itself
            log.info("rosbridge client %d: connection ended: %s", self.number, exc)
        finally:
            self.closed = True
            self.wake.set()
            writer.cancel()
            for sub in self.subs.values():
                self.server.count_drops(sub.topic, sub.dropped)
            self.subs.clear()
            self.server.forget(self)

    async def _write(self) -> None:
        while not self.closed:
            delay = await self._send_ready()
            self.wake.clear()
            if delay is None:
                await self.wake.wait()
            elif delay > 0:
                try:
                    await asyncio.wait_for(self.wake.wait(), delay)
                except TimeoutError:
                    pass

    async def _send_ready(self) -> float | None:
        """Send replies, then one message per subscription whose throttle allows it, until
        nothing is left; the seconds until a throttled one may go (None: nothing waits)."""
        while True:
            sent = False
            while self.replies:
                await self.ws.send(self.replies.popleft())
                sent = True
            now = time.monotonic()
            wait = None
            for sub in list(self.subs.values()):
                if not sub.queue:
                    continue
                if sub.next_at > now:
                    wait = min(wait or 1e9, sub.next_at - now)
                    continue
                message = sub.queue.popleft()
                sub.next_at = now + sub.throttle_s
                await self.ws.send(message.frame(sub.compression))
                sent = True
            if not sent:
                return wait

    # -- replies ---------------------------------------------------------------------------

    def reply(self, payload: dict) -> None:
        """Queue a reply for the writer; too many unread replies end the connection."""
        if len(self.replies) >= MAX_REPLIES:
            log.warning("rosbridge client %d reads no replies: disconnected", self.number)
            self.closed = True
            asyncio.get_running_loop().create_task(self.ws.close(1008, "too many unread replies"))
            return
        self.replies.append(json.dumps(payload, separators=(",", ":")))
        self.wake.set()

    def status(self, level: str, text: str, op_id: Any = None) -> None:
        """A status message, sent when the client's level asks for it."""
        if level == "error":
            self.server.errors += 1
        if LEVELS[level] < self.level:
            return
        payload = {"op": "status", "level": level, "msg": text}
        if op_id is not None:
            payload["id"] = op_id
        self.reply(payload)

    # -- ops ---------------------------------------------------------------------------------

    def _handle(self, frame: str | bytes) -> None:
        op_id = None
        try:
            if len(frame) > self.server.max_frame:
                raise ClientError(f"frame of {len(frame)} bytes is over the "
                                  f"{self.server.max_frame} byte limit: dropped")
            if isinstance(frame, bytes):
                raise ClientError("binary frames are not taken: send JSON text frames")
            try:
                request = json.loads(frame)
            except ValueError as exc:
                raise ClientError(f"malformed JSON: {exc}") from None
            if not isinstance(request, dict) or not isinstance(request.get("op"), str):
                raise ClientError("a rosbridge message is a JSON object with an 'op' string")
            op_id = request.get("id")
            op = request["op"]
            if op in NOT_SERVED:
                raise ClientError(f"op {op!r} is not served: {NOT_SERVED[op]}")
            if op not in OPS:
                raise ClientError(f"unknown op {op!r}; cosim's rosbridge serves "
                                  f"{', '.join(OPS)}")
            getattr(self, f"_op_{op}")(request, op_id)
        except ClientError as exc:
            self.status("error", str(exc), op_id)
        except Exception as exc:  # noqa: BLE001 - a bad op never ends the connection
            log.exception("rosbridge client %d: op failed", self.number)
            self.status("error", f"{type(exc).__name__}: {exc}", op_id)

    def _topic(self, request: dict) -> str:
        topic = request.get("topic")
        if not isinstance(topic, str) or not topic:
            raise ClientError(f"{request['op']}: 'topic' must be a topic name")
        return topic if topic.startswith("/") else "/" + topic

    def _op_subscribe(self, request: dict, op_id: Any) -> None:
        topic = self._topic(request)
        catalog = self.server.catalog
        if topic not in catalog.topics:
            raise ClientError(f"subscribe: no topic {topic} in this run; topics: "
                              f"{', '.join(sorted(catalog.topics))}")
        cls = catalog.topics[topic]
        given = request.get("type")
        if given and not same_type(str(given), ros_type(cls)):
            raise ClientError(f"subscribe: {topic} is {ros_type(cls)}, not {given}")
        throttle = _count(request, "throttle_rate")
        queue = _count(request, "queue_length")
        compression = request.get("compression") or "none"
        if compression not in COMPRESSIONS:
            self.status("warning", f"subscribe: compression {compression!r} is not offered "
                        f"({', '.join(COMPRESSIONS)}); sending JSON", op_id)
            compression = "none"
        sub = self.subs.get(topic)
        if sub is None:
            sub = self.subs[topic] = Subscription(topic)
        new = not sub.ids
        sub.ids[op_id] = (throttle, queue, compression)
        sub.merge()
        self.server.want(topic)
        if new and topic in self.server.latched:  # what a latched topic sent before
            sub.push(self.server.latched[topic])
            self.wake.set()
        self.status("info", f"subscribed to {topic}", op_id)

    def _op_unsubscribe(self, request: dict, op_id: Any) -> None:
        topic = self._topic(request)
        sub = self.subs.get(topic)
        if sub is None:
            self.status("warning", f"unsubscribe: not subscribed to {topic}", op_id)
            return
        if op_id is not None and op_id in sub.ids and len(sub.ids) > 1:
            del sub.ids[op_id]
            sub.merge()
        else:
            self.server.count_drops(topic, sub.dropped)
            del self.subs[topic]
        self.server.unwant_unused()
        self.status("info", f"unsubscribed from {topic}", op_id)

    def _inbox_type(self, topic: str, op: str) -> type:
        inbox = self.server.catalog.inbox
        if inbox is None:
            raise ClientError(f"{op}: {self.server.catalog.no_inbox_text}")
        if topic not in inbox.topics:
            raise ClientError(f"{op}: {topic} is not {self.server.catalog.inbox_what}; it "
                              f"takes {', '.join(sorted(inbox.topics)) or 'none'}")
        return inbox.topics[topic]

    def _op_advertise(self, request: dict, op_id: Any) -> None:
        topic = self._topic(request)
        cls = self._inbox_type(topic, "advertise")
        given = request.get("type")
        if not isinstance(given, str) or not same_type(given, ros_type(cls)):
            raise ClientError(f"advertise: {topic} takes {ros_type(cls)}, not {given}")
        self.advertised.add(topic)
        self.status("info", f"advertised {topic}", op_id)

    def _op_unadvertise(self, request: dict, op_id: Any) -> None:
        topic = self._topic(request)
        if topic not in self.advertised:
            self.status("warning", f"unadvertise: {topic} was not advertised", op_id)
            return
        self.advertised.discard(topic)
        self.status("info", f"unadvertised {topic}", op_id)

    def _op_publish(self, request: dict, op_id: Any) -> None:
        topic = self._topic(request)
        cls = self._inbox_type(topic, "publish")
        try:
            msg = convert.from_json(cls, request.get("msg", {}))
        except convert.MessageError as exc:
            raise ClientError(f"publish to {topic}: wrong message: {exc}") from None
        try:
            self.server.catalog.inbox.put(topic, msg)
        except (KeyError, TypeError) as exc:
            raise ClientError(f"publish to {topic}: {exc}") from None
        self.server.published += 1

    def _op_set_level(self, request: dict, op_id: Any) -> None:
        level = request.get("level")
        if level in LEVELS:
            self.level = LEVELS[level]
        else:
            self.status("warning", f"set_level: {level!r} is not one of {', '.join(LEVELS)}",
                        op_id)

    def _op_call_service(self, request: dict, op_id: Any) -> None:
        name = request.get("service")
        if not isinstance(name, str) or not name:
            raise ClientError("call_service: 'service' must be a service name")
        name = name if name.startswith("/") else "/" + name
        asyncio.get_running_loop().create_task(self._call(name, request, op_id))

    async def _call(self, name: str, request: dict, op_id: Any) -> None:
        answer: dict[str, Any] = {"op": "service_response", "service": name}
        if op_id is not None:
            answer["id"] = op_id
        try:
            values = await self.server.call_service(name, request.get("type"),
                                                    request.get("args"),
                                                    _timeout(request.get("timeout")))
            answer.update(values=values, result=True)
        except (ClientError, ServiceUnavailable, convert.MessageError) as exc:
            self.status("error", f"call_service {name}: {exc}", op_id)
            answer.update(values=str(exc), result=False)
        self.reply(answer)


    def _op_send_action_goal(self, request: dict, op_id: Any) -> None:
        name, action_type = request.get("action"), request.get("action_type")
        if not isinstance(name, str) or not name:
            raise ClientError("send_action_goal: 'action' must be an action name")
        if not isinstance(action_type, str) or not action_type:
            raise ClientError("send_action_goal: 'action_type' must be an action type, e.g. "
                              "simulation_interfaces/SimulateSteps")
        name = name if name.startswith("/") else "/" + name
        cancel = self.goals[op_id] = threading.Event()
        asyncio.get_running_loop().create_task(
            self._goal(name, action_type, request.get("args"), bool(request.get("feedback")),
                       op_id, cancel))

    def _op_cancel_action_goal(self, request: dict, op_id: Any) -> None:
        cancel = self.goals.get(op_id)
        if cancel is None:
            self.status("warning", f"cancel_action_goal: no goal {op_id!r} is running", op_id)
            return
        cancel.set()

    async def _goal(self, name: str, action_type: str, args: Any, feedback: bool, op_id: Any,
                    cancel: threading.Event) -> None:
        loop = asyncio.get_running_loop()
        tag = {"id": op_id} if op_id is not None else {}

        def on_feedback(msg: Any) -> None:  # on the run's executor thread
            if feedback:
                payload = {"op": "action_feedback", **tag, "action": name,
                           "values": convert.to_json(msg)}
                loop.call_soon_threadsafe(self.reply, payload)

        try:
            status, values = await self.server.send_action_goal(
                name, action_type, args, on_feedback, cancel.is_set)
            answer = {"op": "action_result", **tag, "action": name, "values": values,
                      "status": status, "result": True}
        except Exception as exc:  # noqa: BLE001 - any failure is the goal's, told the client
            self.status("error", f"send_action_goal {name}: {exc}", op_id)
            answer = {"op": "action_result", **tag, "action": name, "values": str(exc),
                      "status": STATUS_UNKNOWN, "result": False}
        finally:
            if self.goals.get(op_id) is cancel:
                del self.goals[op_id]
        self.reply(answer)


def service_request(srv: type, args: Any) -> Any:
    """The request of ``srv`` from rosbridge ``args``: an object, a list of the fields in
    order, or nothing."""
    cls = srv.Request
    if args is None or args == []:
        return cls()
    if isinstance(args, list):
        names = list(cls.get_fields_and_field_types())
        if len(args) > len(names):
            raise convert.MessageError(f"{len(args)} args for {len(names)} fields "
                                       f"({', '.join(names)})")
        args = dict(zip(names, args, strict=False))
    return convert.from_json(cls, args, f"{normalise_type(ros_type(srv))} request")


def _count(request: dict, key: str) -> int:
    value = request.get(key, 0) or 0
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value < 0:
        raise ClientError(f"{request['op']}: {key} must be a number of at least 0, "
                          f"not {value!r}")
    return int(value)


def _timeout(value: Any) -> float:
    if isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0:
        return min(float(value), 60.0)
    return SERVICE_TIMEOUT_S
