"""A rosbridge v2 server (JSON text frames, CBOR on request) for roslibpy and roslibjs.

It runs an asyncio loop in a thread of its own. The run offers every message it sees with
``offer`` (never blocking); a message goes to the server's bounded per-topic queue only when
some client subscribed to its topic, and is decoded and encoded once, on the server's
thread, whatever the number of clients. Client messages enter the run through the
catalog's inbox (at a tick boundary, recorded); ``call_service`` reaches the catalog's
services, ``send_action_goal`` its actions (feedback and result as rosbridge sends them), and
a few rosapi services answer what a client may ask a real rosbridge_server
(``/rosapi/topics``, ``/rosapi/services``, ``/rosapi/topic_type``, ``/rosapi/service_type``,
``/rosapi/action_servers``).
"""

from __future__ import annotations

import asyncio
import json
import logging
import threading
from typing import Any

import cbor2

from plan.listen import ListenAddress
from plan.ros_types import ros_type
from plan.timeutil import NS_PER_S
from runtime.cdr.decode import decode
from runtime.live import convert
from runtime.live.channels import BoundedChannels
from runtime.live.endpoints import Catalog, ServiceUnavailable
from runtime.live.rosbridge_session import ClientError, ClientSession, service_request
from runtime.live.schemas import same_type
from runtime.protocol import CLOCK_TOPIC, decode_clock

log = logging.getLogger("cosim")

MAX_FRAME = 8 * 2**20  # a larger frame from a client gets an error status
HARD_FRAME = 64 * 2**20  # a larger one closes the connection (websockets' own limit)
QUEUE_DEPTH = 64  # per topic, between the run and the server's thread
CLOSE_WAIT_S = 1.0
ACTION_TIMEOUT_S = 10.0  # for an action server to appear and answer a goal (not its result)
ROSAPI = ("/rosapi/topics", "/rosapi/services", "/rosapi/topic_type", "/rosapi/service_type",
          "/rosapi/action_servers")


class OutgoingMessage:
    """One message of the run, encoded for clients on demand, once per encoding."""

    __slots__ = ("topic", "cls", "data", "stamp_ns", "_frames", "_decoded")

    def __init__(self, topic: str, cls: type, data: bytes, stamp_ns: int):
        self.topic, self.cls, self.data, self.stamp_ns = topic, cls, data, stamp_ns
        self._frames: dict[str, str | bytes] = {}
        self._decoded = None

    def frame(self, compression: str) -> str | bytes:
        """The 'publish' op for a client: JSON text, or CBOR ('cbor', 'cbor-raw')."""
        frame = self._frames.get(compression)
        if frame is None:
            frame = self._frames[compression] = self._encode(compression)
        return frame

    def _encode(self, compression: str) -> str | bytes:
        if compression == "cbor-raw":
            secs, nsecs = divmod(self.stamp_ns, NS_PER_S)
            return cbor2.dumps({"op": "publish", "topic": self.topic,
                                "msg": {"secs": secs, "nsecs": nsecs, "bytes": self.data}})
        if self._decoded is None:
            self._decoded = decode(self.data, self.cls)
        if compression == "cbor":
            return cbor2.dumps({"op": "publish", "topic": self.topic,
                                "msg": convert.to_json(self._decoded, binary=True)})
        body = json.dumps(convert.to_json(self._decoded), separators=(",", ":"))
        return f'{{"op":"publish","topic":{json.dumps(self.topic)},"msg":{body}}}'


class RosbridgeServer:
    """Listens on ``address`` and serves rosbridge clients from its own thread."""

    def __init__(self, address: ListenAddress, catalog: Catalog, max_frame: int = MAX_FRAME):
        self.address = address
        self.catalog = catalog
        self.max_frame = max_frame
        self.port: int | None = None
        self.clients: set[ClientSession] = set()
        self.clients_total = 0
        self.clients_max = 0
        self.published = 0
        self.errors = 0
        self.dropped_by_clients: dict[str, int] = {}
        self._wanted: frozenset[str] = frozenset()
        self._clock = b""
        self.latched: dict[str, OutgoingMessage] = {}  # the last message of latched topics
        self._loop = asyncio.new_event_loop()
        self._queue = BoundedChannels(QUEUE_DEPTH, on_first=self._wake)
        self._thread = threading.Thread(target=self._loop.run_forever, name="cosim-rosbridge",
                                        daemon=True)
        self._server = None

    # -- life --------------------------------------------------------------------------------

    def start(self) -> int:
        """Listen (OSError when the address cannot be had); return the port."""
        self._thread.start()
        future = asyncio.run_coroutine_threadsafe(self._listen(), self._loop)
        try:
            self.port = future.result(timeout=10)
        except BaseException:
            self._stop_loop()
            raise
        return self.port

    async def _listen(self) -> int:
        from websockets.asyncio.server import serve

        self._server = await serve(self._serve_client, self.address.host, self.address.port,
                                   max_size=HARD_FRAME, compression=None, max_queue=64)
        return self._server.sockets[0].getsockname()[1]

    def close(self) -> None:
        """Close every connection and stop the thread."""
        self._queue.close()
        if self._thread.is_alive():
            try:
                asyncio.run_coroutine_threadsafe(self._shutdown(), self._loop).result(timeout=5)
            except Exception as exc:  # noqa: BLE001 - closing is best effort
                log.warning("rosbridge: closing: %s", exc)
        self._stop_loop()

    async def _shutdown(self) -> None:
        """Say goodbye to every client (a client that does not read is cut off), stop
        listening, and end every task of the loop."""
        if self._server is not None:
            self._server.close(close_connections=False)
        await asyncio.gather(*(_close_client(s.ws) for s in list(self.clients)))
        if self._server is not None:
            try:
                await asyncio.wait_for(self._server.wait_closed(), CLOSE_WAIT_S)
            except TimeoutError:
                pass
        tasks = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

    def _stop_loop(self) -> None:
        if self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(timeout=5)
        if not self._thread.is_alive():
            self._loop.close()

    def stats(self) -> dict[str, Any]:
        """For the manifest: where it listened, clients, messages taken and dropped."""
        dropped = dict(self.dropped_by_clients)
        for session in list(self.clients):
            for sub in session.subs.values():
                dropped[sub.topic] = dropped.get(sub.topic, 0) + sub.dropped
        for topic, n in self._queue.dropped.items():
            dropped[topic] = dropped.get(topic, 0) + n
        return {"address": f"{self.address.host}:{self.port}", "clients": self.clients_total,
                "clients_at_once": self.clients_max, "published_by_clients": self.published,
                "errors": self.errors,
                "dropped": {t: n for t, n in sorted(dropped.items()) if n}}

    # -- from the run (any thread) --------------------------------------------------------------

    def offer(self, topic: str, data: bytes) -> None:
        """A message of the run; queued only when a client subscribed to ``topic``."""
        if topic == CLOCK_TOPIC:
            self._clock = data  # stamps messages without a header (decoded when used)
        if topic in self._wanted or topic in self.catalog.latched:
            self._queue.put(topic, data)

    def _wake(self) -> None:
        try:
            self._loop.call_soon_threadsafe(self._dispatch)
        except RuntimeError:
            pass  # the loop is closed: the run is ending

    # -- on the server's thread ---------------------------------------------------------------

    def _dispatch(self) -> None:
        clock_ns = decode_clock(self._clock) if self._clock else 0
        for topic, data in self._queue.take():
            cls = self.catalog.topics[topic]
            message = OutgoingMessage(topic, cls, data,
                                      self.catalog.stamp_of(topic, data, clock_ns))
            if topic in self.catalog.latched:
                self.latched[topic] = message
            for session in self.clients:
                sub = session.subs.get(topic)
                if sub is not None:
                    sub.push(message)
                    session.wake.set()

    async def _serve_client(self, websocket) -> None:
        self.clients_total += 1
        session = ClientSession(self, websocket, self.clients_total)
        self.clients.add(session)
        self.clients_max = max(self.clients_max, len(self.clients))
        log.info("rosbridge client %d connected from %s", session.number,
                 websocket.remote_address)
        await session.serve()
        log.info("rosbridge client %d left", session.number)

    def forget(self, session: ClientSession) -> None:
        """A client left."""
        self.clients.discard(session)
        self.unwant_unused()

    def want(self, topic: str) -> None:
        """Some client subscribed to ``topic``."""
        self._wanted = self._wanted | {topic}

    def unwant_unused(self) -> None:
        """Stop queueing topics no client subscribes to any more."""
        self._wanted = frozenset(t for s in self.clients for t in s.subs)

    def count_drops(self, topic: str, n: int) -> None:
        """Keep the drops of a subscription that ended."""
        if n:
            self.dropped_by_clients[topic] = self.dropped_by_clients.get(topic, 0) + n

    async def call_service(self, name: str, type_name: Any, args: Any, timeout_s: float
                           ) -> dict:
        """Serve a call_service op: a rosapi question or a service of the catalog."""
        await self._services_come(timeout_s)
        if name in ROSAPI:
            return self._rosapi(name, args if isinstance(args, dict) else {})
        services = self.catalog.services
        known = services.types() if services is not None else {}
        if name not in known:
            offered = ", ".join(sorted([*known, *ROSAPI]))
            raise ClientError(f"no service {name}; services: {offered}")
        srv = known[name]
        if type_name and not same_type(str(type_name), ros_type(srv), "srv"):
            raise ClientError(f"{name} is {ros_type(srv)}, not {type_name}")
        request = service_request(srv, args)
        response = await asyncio.to_thread(services.call, name, request, timeout_s)
        return convert.to_json(response)

    async def send_action_goal(self, name: str, type_name: str, args: Any, on_feedback,
                               cancelled) -> tuple[int, Any]:
        """Serve a send_action_goal op: a goal for one of the catalog's actions; its status
        and result once it ends (feedback goes to ``on_feedback`` meanwhile)."""
        await self._services_come(ACTION_TIMEOUT_S)
        actions = self.catalog.actions
        known = actions.types() if actions is not None else {}
        if name not in known:
            raise ClientError(f"no action {name}; actions: {', '.join(sorted(known)) or 'none'}")
        action = known[name]
        if not same_type(type_name, ros_type(action), "action"):
            raise ClientError(f"{name} is {ros_type(action)}, not {type_name}")
        goal = convert.from_json(action.Goal, args if args not in (None, []) else {},
                                 f"{ros_type(action)} goal")
        status, result = await asyncio.to_thread(actions.run_goal, name, goal, on_feedback,
                                                 cancelled, ACTION_TIMEOUT_S)
        return status, convert.to_json(result)

    async def _services_come(self, timeout_s: float) -> None:
        """A client that calls before the run's services are up (the nodes still start)
        waits for them, up to ``timeout_s``."""
        ready = self.catalog.services_ready
        if ready is not None and not ready.is_set():
            await asyncio.to_thread(ready.wait, timeout_s)

    def _rosapi(self, name: str, args: dict) -> dict:
        topics = self.catalog.topics
        services = self.catalog.services.types() if self.catalog.services else {}
        if name == "/rosapi/topics":
            ordered = sorted(topics)
            return {"topics": ordered, "types": [ros_type(topics[t]) for t in ordered]}
        if name == "/rosapi/services":
            return {"services": sorted([*services, *ROSAPI])}
        if name == "/rosapi/action_servers":
            actions = self.catalog.actions.types() if self.catalog.actions else {}
            return {"action_servers": sorted(actions)}
        if name == "/rosapi/topic_type":
            cls = topics.get(args.get("topic", ""))
            return {"type": ros_type(cls) if cls else ""}
        srv = services.get(args.get("service", ""))
        return {"type": ros_type(srv) if srv else ""}


async def _close_client(websocket) -> None:
    """Close one connection; a client that does not take the close frame is cut off."""
    try:
        await asyncio.wait_for(websocket.close(1001, "the run is over"), CLOSE_WAIT_S)
    except Exception:  # noqa: BLE001 - whatever the state, the connection goes
        websocket.transport.abort()


__all__ = ["RosbridgeServer", "ServiceUnavailable"]
