"""The Foxglove live view: a Foxglove WebSocket server (``foxglove-sdk``) that streams every
topic of the run as CDR with ``ros2msg`` schemas and broadcasts sim time as the server's
time, so Foxglove's panels (3D with /tf, images, plots) follow the run.

The run offers messages with ``offer`` (never blocking): they wait in bounded per-topic
queues (oldest dropped, counted) only while some client subscribes to the topic, and a
thread of this module hands them to the SDK, whose per-client backlog is bounded too (it
drops a slow client's oldest messages). Simulation control is offered twice: as services
(the catalog's, e.g. ``/cosim/pause``, ``/cosim/step``, ``/cosim/reset``, CDR-encoded with
their ``ros2msg`` schemas) and as the app's playback controls (play and pause).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

import foxglove
from foxglove.websocket import (
    Capability,
    PlaybackCommand,
    PlaybackState,
    PlaybackStatus,
)
from rclpy.serialization import deserialize_message, serialize_message

from plan.listen import ListenAddress
from plan.ros_types import ros_type
from runtime.live.channels import BoundedChannels
from runtime.live.endpoints import Catalog, ServiceUnavailable
from runtime.live.schemas import message_schema, service_schemas
from runtime.protocol import CLOCK_TOPIC, decode_clock

log = logging.getLogger("cosim")

QUEUE_DEPTH = 32  # per topic, between the run and the server's thread
CLIENT_BACKLOG = 256  # messages the SDK keeps per client before dropping its oldest
STATE_PERIOD_S = 0.25
YIELD_EVERY = 16  # messages logged between two yields of the GIL (the run's threads wait)
TIME_PERIOD_S = 0.02  # the server's time goes to clients at most this often (wall clock)
PAUSE_SERVICE = "/cosim/pause"
SERVICE_TIMEOUT_S = 10.0
STOP_WAIT_S = 2.0


class FoxgloveLive:
    """A Foxglove WebSocket server fed from the run."""

    def __init__(self, address: ListenAddress, catalog: Catalog, name: str,
                 end_ns: int | None = None, control_later: bool = False):
        self.address = address
        self.catalog = catalog
        self.name = name
        self.end_ns = end_ns
        self.control_later = control_later  # services come with attach_services
        self.port: int | None = None
        self.context = foxglove.Context()
        self.channels = {topic: self._channel(topic, cls) for topic, cls in catalog.topics.items()}
        self._wanted: dict[str, int] = {}
        self._wanted_lock = threading.Lock()
        self._queue = BoundedChannels(QUEUE_DEPTH)
        self._latched: dict[str, tuple[bytes, int]] = {}  # topic -> last (data, log time)
        self._replay: set[str] = set()  # latched topics a client just subscribed to
        self._clock_ns = 0
        self._playing = True
        self._server = None
        self._thread = threading.Thread(target=self._forward, name="cosim-foxglove",
                                        daemon=True)
        self.clients_total = 0
        self.clients: dict[int, int] = {}  # client id -> its subscriptions
        self.clients_max = 0

    def _channel(self, topic: str, cls: type):
        type_name = ros_type(cls)
        schema = foxglove.Schema(name=type_name, encoding="ros2msg",
                                 data=message_schema(type_name).encode())
        return foxglove.Channel(topic, schema=schema, message_encoding="cdr",
                                context=self.context)

    # -- life --------------------------------------------------------------------------------

    def start(self) -> int:
        """Listen (RuntimeError from the SDK when the address cannot be had); the port."""
        services = self.catalog.services.types() if self.catalog.services else {}
        capabilities = [Capability.Time]
        if services or self.control_later:
            capabilities.append(Capability.Services)
        has_pause = PAUSE_SERVICE in services or self.control_later
        playback = (0, self.end_ns) if self.end_ns and has_pause else None
        self._server = foxglove.start_server(
            name=self.name, host=self.address.host, port=self.address.port,
            capabilities=capabilities, server_listener=_Listener(self),
            supported_encodings=["cdr"], services=[self._service(n, s)
                                                   for n, s in services.items()],
            context=self.context, playback_time_range=playback,
            message_backlog_size=CLIENT_BACKLOG)
        self.port = self._server.port
        self._thread.start()
        return self.port

    def close(self) -> None:
        """Stop forwarding and stop the server, waiting at most ``STOP_WAIT_S`` for it: the
        SDK's stop waits for every client to take its close frame, which a stuck client never
        does; the stop then finishes in the background (or with the process)."""
        self._queue.close()
        if self._thread.is_alive():
            self._thread.join(timeout=5)
        for channel in self.channels.values():
            channel.close()
        if self._server is not None:
            stopping = threading.Thread(target=self._server.stop, name="cosim-foxglove-stop",
                                        daemon=True)
            stopping.start()
            stopping.join(STOP_WAIT_S)
            if stopping.is_alive():
                log.warning("live view: a client does not read; stopped without waiting for it")
                _keep_runtime_at_exit()

    def attach_services(self) -> None:
        """Offer the catalog's services, which came after the server started."""
        services = self.catalog.services.types() if self.catalog.services else {}
        if services:
            self._server.add_services([self._service(n, s) for n, s in services.items()])

    def stats(self) -> dict[str, Any]:
        """For the manifest: where it listened, clients, messages dropped per topic."""
        return {"address": f"{self.address.host}:{self.port}", "clients": self.clients_total,
                "clients_at_once": self.clients_max,
                "dropped": {t: n for t, n in sorted(self._queue.dropped.items()) if n}}

    # -- from the run (any thread) ----------------------------------------------------------

    def offer(self, topic: str, data: bytes) -> None:
        """A message of the run: queued while some client subscribes to its topic (/clock
        always: it is the server's time)."""
        if topic in self._wanted or topic == CLOCK_TOPIC or topic in self.catalog.latched:
            self._queue.put(topic, data)

    # -- the forwarding thread ----------------------------------------------------------------

    def _forward(self) -> None:
        next_state = next_time = 0.0
        sent_ns = -1
        while True:
            # what was offered before the close is sent too: read closed, then take all
            closed = self._queue.closed
            items = self._queue.take(timeout_s=0.1)
            for i, (topic, data) in enumerate(items):
                if i % YIELD_EVERY == YIELD_EVERY - 1:
                    time.sleep(0)
                if topic == CLOCK_TOPIC:
                    stamp = self._clock_ns = decode_clock(data)
                else:
                    stamp = self.catalog.stamp_of(topic, data, self._clock_ns)
                if topic in self.catalog.latched:
                    self._latched[topic] = (data, stamp)
                if topic in self._wanted:
                    self.channels[topic].log(data, log_time=stamp)
            while self._replay:  # a new subscriber of a latched topic gets its last message
                topic = self._replay.pop()
                if topic in self._latched:
                    data, stamp = self._latched[topic]
                    self.channels[topic].log(data, log_time=stamp)
            now = time.monotonic()
            if self._clock_ns != sent_ns and now >= next_time:
                next_time, sent_ns = now + TIME_PERIOD_S, self._clock_ns
                self._server.broadcast_time(self._clock_ns)
            if self.end_ns and now >= next_state:
                next_state = now + STATE_PERIOD_S
                self._server.broadcast_playback_state(self._state(None))
            if closed:
                break
        if self._clock_ns != sent_ns:  # the run's last time
            self._server.broadcast_time(self._clock_ns)

    def _state(self, request_id: str | None) -> PlaybackState:
        status = PlaybackStatus.Playing if self._playing else PlaybackStatus.Paused
        if self.end_ns and self._clock_ns >= self.end_ns:
            status = PlaybackStatus.Ended
        return PlaybackState(status=status, current_time=self._clock_ns, playback_speed=1.0,
                             did_seek=False, request_id=request_id)

    # -- simulation control ---------------------------------------------------------------------

    def _service(self, name: str, srv: type):
        type_name = ros_type(srv)
        request_text, response_text = service_schemas(type_name)
        schema = foxglove.ServiceSchema(
            type_name,
            request=foxglove.MessageSchema(encoding="cdr", schema=foxglove.Schema(
                name=f"{type_name}_Request", encoding="ros2msg", data=request_text.encode())),
            response=foxglove.MessageSchema(encoding="cdr", schema=foxglove.Schema(
                name=f"{type_name}_Response", encoding="ros2msg",
                data=response_text.encode())))

        def handle(request) -> bytes:  # on one of the SDK's blocking threads
            try:
                message = deserialize_message(request.payload, srv.Request)
            except Exception as exc:  # noqa: BLE001 - reported to the caller
                raise ValueError(f"{name}: the request is not a CDR {type_name} request "
                                 f"({exc})") from None
            response = self.catalog.services.call(name, message, SERVICE_TIMEOUT_S)
            if name == PAUSE_SERVICE and getattr(response, "success", False):
                self._playing = not message.data
            return serialize_message(response)

        return foxglove.Service(name, schema=schema, handler=handle)

    def playback(self, command, request_id: str) -> PlaybackState:
        """The app's play or pause button: resume or pause the run (asynchronously: the
        SDK's poll loop must not wait for the run)."""
        pause = command == PlaybackCommand.Pause
        self._playing = not pause
        services = self.catalog.services
        if services is not None and PAUSE_SERVICE in services.types():
            request = services.types()[PAUSE_SERVICE].Request(data=pause)
            threading.Thread(target=_call_quietly, args=(services, request),
                             name="cosim-foxglove-playback", daemon=True).start()
        return self._state(request_id)

    def subscribed(self, topic: str, delta: int) -> None:
        """A client (un)subscribed to ``topic``."""
        with self._wanted_lock:
            count = self._wanted.get(topic, 0) + delta
            wanted = dict(self._wanted)
            if count > 0:
                wanted[topic] = count
            else:
                wanted.pop(topic, None)
            self._wanted = wanted  # replaced whole: offer() reads it without the lock


def _keep_runtime_at_exit() -> None:
    """The SDK drops its runtime at exit, which waits for (or aborts on) the stop still
    waiting for a stuck client: leave both to the end of the process instead."""
    import atexit

    from foxglove import _foxglove_py

    atexit.unregister(_foxglove_py.shutdown)


def _call_quietly(services, request) -> None:
    try:
        services.call(PAUSE_SERVICE, request, SERVICE_TIMEOUT_S)
    except ServiceUnavailable as exc:
        log.warning("live view: playback control: %s", exc)


class _Listener:
    """The SDK's callbacks (on its threads): subscriptions, clients, playback control."""

    def __init__(self, live: FoxgloveLive):
        self.live = live

    def on_subscribe(self, client, channel) -> None:
        """A client subscribed to a channel (clients are counted from their first)."""
        live = self.live
        if client.id not in live.clients:
            live.clients_total += 1
        live.clients[client.id] = live.clients.get(client.id, 0) + 1
        live.clients_max = max(live.clients_max, len(live.clients))
        live.subscribed(channel.topic, +1)
        if channel.topic in live.catalog.latched:
            live._replay.add(channel.topic)

    def on_unsubscribe(self, client, channel) -> None:
        """A client unsubscribed from a channel (or left)."""
        live = self.live
        left = live.clients.get(client.id, 1) - 1
        if left > 0:
            live.clients[client.id] = left
        else:
            live.clients.pop(client.id, None)
        live.subscribed(channel.topic, -1)

    def on_playback_control_request(self, request):
        """Play or pause from the app's playback bar."""
        return self.live.playback(request.playback_command, request.request_id)
