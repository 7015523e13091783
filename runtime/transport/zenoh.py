"""The zenoh transport: the same CDR bytes as ros2, carried by eclipse-zenoh sessions.

Topology (a mesh of direct TCP links, no multicast anywhere):
- The orchestrator's session is a zenoh peer listening on loopback only
  (``tcp/127.0.0.1:<free port>``, or the scenario's ``zenoh.listen`` endpoints). When it
  opens, it exports its endpoints to the environment as ``COSIM_ZENOH_CONNECT`` (process
  plumbing: the address exists only once the session is open) so the node processes it
  spawns inherit them (the previous value is restored on close). It also connects to the
  scenario's ``zenoh.connect`` endpoints, e.g. a zenohd on another host.
- A node's session is a peer that connects to ``COSIM_ZENOH_CONNECT`` and listens on a free
  port of its own address on the route to that endpoint (127.0.0.1 for a loopback one, the
  host's interface address for a remote one). Gossip scouting (over those links, never
  multicast) tells every peer the others' endpoints, and each pair links directly, so data
  goes node to node in one hop. (A star, nodes as clients routed by an orchestrator
  router, was measured first: twice the CPU per tick in the orchestrator and 1.5x in the
  nodes, and fewer ticks/s; see bench/README.md.)
- A session opened with no ``COSIM_ZENOH_CONNECT`` (a ``cosim-node`` run by hand, a
  benchmark) is a root itself.

Key expressions follow rmw_zenoh's layout: ``<domain>/<topic without leading
slash>/<type>/<type hash>``, e.g. ``5/clock/rosgraph_msgs::msg::dds_::Clock_/RIHS01_692f...``,
with ``<domain>`` = ``ROS_DOMAIN_ID`` (default 0) so parallel runs never see each other's
data. The type hash is read from the package's installed type description
(``share/<pkg>/msg/<Type>.json``); ``TypeHashNotSupported`` when it cannot be found.

Sequence numbers: every publisher numbers its messages 1, 2, ... per topic and sends the
number as the sample's 8-byte little-endian attachment; ``Received.sequence`` returns it,
so the runtime's gap check works exactly as over DDS.

Discovery (``matched()``): every publisher and subscription declares a liveliness token
``@cosim/<domain>/<pub|sub>/<topic without leading slash>/<participant>``; one liveliness
subscriber per session counts them. A publisher's count is the number of subscription
tokens of its topic, and 0 while zenoh's own matching status says no subscriber is routed
yet (peers route only to their direct neighbours, so "matched" means the direct link is up
and data can flow, as DDS discovery does).

Large messages: zenoh's shared-memory transport optimisation (on by default: messages over
3 KiB between sessions of one host travel through a shared-memory pool) is kept;
the run option ``zenoh_shm=False`` (``--no-zenoh-shm``) turns it off (bench/zenoh_chain.py
measures both).

Sending: publishers are not express (``express`` off, zenoh's default): a message is queued in
the link's current batch and zenoh's transmit thread writes the batch, so messages published
back to back (the orchestrator's /clock for the ticks of its window, a node's outputs) share
one write and one wake-up of the receiver. Express (every message written at once) cost
20-35% more CPU per tick in the 3-node chain (bench/README.md, "zenoh"); the run option
``zenoh_express=True`` (``--zenoh-express``) brings it back, for comparisons.

Receiving: every subscriber is a direct callback (run on zenoh's network thread) that
appends ``Received`` items to one queue per participant; ``wait()`` blocks on that queue, so
a node blocks on one thing whatever the number of its inputs. zenoh's threads are not Python
threads: each callback takes the GIL through ``PyGILState_Ensure``, which builds a Python thread
state and tears it down again every time (about 30 us of CPU a message, half of what a round
trip cost). ``_keep_thread_state`` makes that state live as long as the thread instead
(bench/README.md, "zenoh"); zenoh's own FIFO handlers are as cheap but cannot wait on several
subscriptions at once or with a timeout.
"""

from __future__ import annotations

import ctypes
import json
import os
import queue
import socket
import sys
import threading
from functools import cache
from pathlib import Path

import zenoh
import zenoh.ext

from plan.options import TransportSettings
from runtime.transport.base import Publisher, Received, Subscription, Transport

CONNECT_ENV = "COSIM_ZENOH_CONNECT"
DEFAULT_LISTEN = "tcp/127.0.0.1:0"
LIVELINESS_ROOT = "@cosim"
_NO_HASH = "TypeHashNotSupported"


_threads_kept: set[int] = set()


def _keep_thread_state() -> None:
    """Called first in every callback zenoh runs on its own threads: the first call on a thread
    takes one more hold on the thread state PyO3's ``PyGILState_Ensure`` just made for it and
    never lets go, so later callbacks on that thread find it alive instead of building and
    destroying one per message."""
    ident = threading.get_ident()
    if ident not in _threads_kept:
        _threads_kept.add(ident)
        ctypes.pythonapi.PyGILState_Ensure()


def domain_id() -> int:
    """The ROS domain id (ROS_DOMAIN_ID, default 0): the first chunk of every key."""
    return int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)


def type_name(msg_type: type) -> str:
    """rmw_zenoh's type name: 'rosgraph_msgs::msg::dds_::Clock_'."""
    package, kind = msg_type.__module__.split(".")[:2]
    return f"{package}::{kind}::dds_::{msg_type.__name__}_"


@cache
def type_hash(msg_type: type) -> str:
    """The RIHS01 type hash from the package's installed type description, if any."""
    package, kind = msg_type.__module__.split(".")[:2]
    candidates = [Path(sys.prefix) / "share" / package / kind / f"{msg_type.__name__}.json"]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            candidates.append(Path(prefix) / "share" / package / kind
                              / f"{msg_type.__name__}.json")
    for path in candidates:
        try:
            hashes = json.loads(path.read_text())["type_hashes"]
        except (OSError, ValueError, KeyError):
            continue
        wanted = f"{package}/{kind}/{msg_type.__name__}"
        for entry in hashes:
            if entry.get("type_name") == wanted:
                return entry["hash_string"]
    return _NO_HASH


def topic_key(topic: str, msg_type: type, domain: int | None = None) -> str:
    """The data key expression of a topic (rmw_zenoh layout, see the module docstring)."""
    domain = domain_id() if domain is None else domain
    return f"{domain}/{topic.strip('/')}/{type_name(msg_type)}/{type_hash(msg_type)}"


def liveliness_key(role: str, topic: str, participant: str, domain: int | None = None) -> str:
    """The liveliness token announcing one publisher ('pub') or subscription ('sub')."""
    domain = domain_id() if domain is None else domain
    return f"{LIVELINESS_ROOT}/{domain}/{role}/{topic.strip('/')}/{participant}"


def _endpoints(text: str | None) -> list[str]:
    return [e.strip() for e in (text or "").split(",") if e.strip()]


def _with_free_port(endpoint: str) -> str:
    """'tcp/127.0.0.1:0' -> 'tcp/127.0.0.1:<a free port>' (zenoh does not tell us its port)."""
    proto, _, address = endpoint.partition("/")
    host, _, port = address.rpartition(":")
    if proto not in ("tcp", "udp") or port != "0":
        return endpoint
    bare = host.strip("[]")
    family = socket.AF_INET6 if ":" in bare else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.bind((bare, 0))
        return f"{proto}/{host}:{s.getsockname()[1]}"


def _route_address(endpoint: str) -> str:
    """This host's address on the route to ``endpoint`` ('127.0.0.1' for a loopback one)."""
    address = endpoint.partition("/")[2].split("#")[0]
    host, _, port = address.rpartition(":")
    bare = host.strip("[]")
    family = socket.AF_INET6 if ":" in bare else socket.AF_INET
    with socket.socket(family, socket.SOCK_DGRAM) as s:
        s.connect((bare, int(port or 7447)))
        local = s.getsockname()[0]
    return f"[{local}]" if family == socket.AF_INET6 else local


def session_config(mode: str, listen: list[str], connect: list[str], shm: bool = True
                   ) -> zenoh.Config:
    """A zenoh config: ``mode``, explicit endpoints, gossip scouting only (no multicast)."""
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("listen/endpoints", json.dumps(listen))
    config.insert_json5("connect/endpoints", json.dumps(connect))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("scouting/gossip/enabled", "true")  # learn peers from the root
    if not shm:  # large messages go through shared memory by default
        config.insert_json5("transport/shared_memory/enabled", "false")
    if connect:
        config.insert_json5("connect/timeout_ms", "30000")
        config.insert_json5("connect/exit_on_failure", "true")
    return config


class ZenohPublisher(Publisher):
    """A zenoh publisher numbering its messages in the attachment (reliable, blocking, batched
    unless the transport is express: see the module docstring). A latched one is an
    advanced publisher that caches its last ``depth`` samples for late advanced
    subscriptions, as rmw_zenoh does for transient-local durability."""

    def __init__(self, transport: ZenohTransport, topic: str, msg_type: type, depth: int = 1,
                 latched: bool = False):
        self.topic = topic
        self._transport = transport
        options = {"reliability": zenoh.Reliability.RELIABLE,
                   "congestion_control": zenoh.CongestionControl.BLOCK,
                   "express": transport.express}
        key = topic_key(topic, msg_type)
        if latched:
            self._pub = zenoh.ext.declare_advanced_publisher(
                transport.session, key, cache=zenoh.ext.CacheConfig(max_samples=depth),
                publisher_detection=True,  # sequence numbers: no timestamping needed
                sample_miss_detection=zenoh.ext.MissDetectionConfig(heartbeat=None,
                                                                    sporadic_heartbeat=None),
                **options)
        else:
            self._pub = transport.session.declare_publisher(key, **options)
        self._latched = latched
        self._put = self._pub.put
        self._sequence = 0
        self._token = transport.session.liveliness().declare_token(
            liveliness_key("pub", topic, transport.participant))

    def publish(self, data: bytes) -> None:
        """Send CDR bytes with the next sequence number attached."""
        self._sequence += 1
        self._put(data, attachment=self._sequence.to_bytes(8, "little"))

    def matched(self) -> int:
        """Subscriptions announced for this topic, once zenoh routes data to at least one."""
        count = self._transport.count("sub", self.topic)
        if count and not self._latched and not self._pub.matching_status.matching:
            return 0  # (an advanced publisher has no matching status; its cache serves late)
        return count


def _once_each(deliver):
    """``deliver`` for an advanced subscriber, without a second copy of a cached sample: its
    history query at declaration and its detection of the publisher a moment later can both
    answer with the same sample (seen on a loaded machine). Samples of one publisher (its
    zenoh entity id) come in order of its sequence numbers, so one already passed is a copy;
    a publisher started again is another entity and starts afresh."""
    last: dict[str, int] = {}  # publisher entity -> the last sequence number delivered
    lock = threading.Lock()

    def once(sample: zenoh.Sample) -> None:
        info = sample.source_info
        if info is not None and info.source_id is not None:
            source = str(info.source_id)
            with lock:
                if source in last and info.source_sn <= last[source]:
                    return
                last[source] = info.source_sn
        deliver(sample)
    return once


class ZenohSubscription(Subscription):
    """A zenoh subscriber delivering into its participant's queue."""

    def __init__(self, transport: ZenohTransport, topic: str, msg_type: type,
                 latched: bool = False):
        self.topic = topic
        self._transport = transport
        put = transport._inbox.put

        def deliver(sample: zenoh.Sample, topic: str = topic, kept: set = _threads_kept,
                    ident=threading.get_ident, number=int.from_bytes) -> None:
            if ident() not in kept:  # (bound defaults: this runs for every message)
                _keep_thread_state()
            attachment = sample.attachment
            put(Received(topic, sample.payload.to_bytes(),
                         number(attachment.to_bytes(), "little")
                         if attachment is not None else None))

        key = topic_key(topic, msg_type)
        if latched:  # also asks latched (advanced) publishers for what they cached
            handler = zenoh.handlers.Callback(_once_each(deliver), indirect=False)
            self._sub = zenoh.ext.declare_advanced_subscriber(
                transport.session, key, handler,
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True))
        else:
            self._sub = transport.session.declare_subscriber(
                key, zenoh.handlers.Callback(deliver, indirect=False))
        self._token = transport.session.liveliness().declare_token(
            liveliness_key("sub", topic, transport.participant))

    def matched(self) -> int:
        """Publishers announced for this topic."""
        return self._transport.count("pub", self.topic)


class ZenohTransport(Transport):
    """One zenoh session per participant (see the module docstring for the topology)."""

    def __init__(self, participant: str, settings: TransportSettings | None = None):
        settings = settings or TransportSettings(kind="zenoh")
        self.participant = participant
        self.express = settings.zenoh_express
        self.domain = domain_id()
        connect = _endpoints(os.environ.get(CONNECT_ENV))
        self.root = not connect
        self._exported: tuple[bool, str | None] | None = None
        if self.root:
            listen = [_with_free_port(e) for e in
                      list(settings.zenoh_listen) or [DEFAULT_LISTEN]]
            config = session_config("peer", listen, list(settings.zenoh_connect),
                                    settings.zenoh_shm)
            self.endpoints = listen
        else:  # listen where the orchestrator's peers can reach us, for direct links
            listen = [_with_free_port(f"tcp/{_route_address(connect[0])}:0")]
            config = session_config("peer", listen, connect, settings.zenoh_shm)
            self.endpoints = connect
        self.session = zenoh.open(config)
        if self.root:  # children (node processes) connect here
            self._exported = (CONNECT_ENV in os.environ, os.environ.get(CONNECT_ENV))
            os.environ[CONNECT_ENV] = ",".join(self.endpoints)
        self._inbox: queue.SimpleQueue[Received] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._alive: dict[tuple[str, str], set[str]] = {}
        prefix = f"{LIVELINESS_ROOT}/{self.domain}/"
        self._prefix_len = len(prefix)
        self._liveliness = self.session.liveliness().declare_subscriber(
            prefix + "**", zenoh.handlers.Callback(self._on_token, indirect=False),
            history=True)
        self._entities: list = []

    def _on_token(self, sample: zenoh.Sample) -> None:
        _keep_thread_state()
        rest = str(sample.key_expr)[self._prefix_len:]
        role, _, rest = rest.partition("/")
        topic, _, participant = rest.rpartition("/")
        key = (role, "/" + topic)
        with self._lock:
            owners = self._alive.setdefault(key, set())
            if sample.kind == zenoh.SampleKind.PUT:
                owners.add(participant)
            else:
                owners.discard(participant)

    def count(self, role: str, topic: str) -> int:
        """Participants with a live ``role`` ('pub' or 'sub') token on ``topic``."""
        with self._lock:
            return len(self._alive.get((role, "/" + topic.strip("/")), ()))

    def publisher(self, topic: str, msg_type: type, depth: int,
                  latched: bool = False) -> ZenohPublisher:
        """A reliable, blocking-congestion zenoh publisher (nothing is dropped); ``latched``:
        one that keeps its last ``depth`` samples for late subscriptions."""
        pub = ZenohPublisher(self, topic, msg_type, depth, latched)
        self._entities.append(pub)
        return pub

    def subscription(self, topic: str, msg_type: type, depth: int,
                     latched: bool = False) -> ZenohSubscription:
        """A zenoh subscriber; its queue is unbounded, so ``depth`` is never a limit.
        ``latched`` also receives what latched publishers sent before it was declared."""
        sub = ZenohSubscription(self, topic, msg_type, latched)
        self._entities.append(sub)
        return sub

    def wait(self, timeout_ns: int) -> list[Received]:
        """Block up to ``timeout_ns`` for the first message, then take all that are queued."""
        inbox = self._inbox
        out: list[Received] = []
        try:
            out.append(inbox.get_nowait() if inbox.qsize() else
                       inbox.get(timeout=max(timeout_ns, 0) / 1e9))
        except queue.Empty:
            return out
        while True:
            try:
                out.append(inbox.get_nowait())
            except queue.Empty:
                return out

    def close(self) -> None:
        """Close the session; a root restores the environment it exported."""
        try:
            self._entities.clear()
            self.session.close()
        finally:
            if self._exported is not None:
                had, value = self._exported
                if had:
                    os.environ[CONNECT_ENV] = value
                else:
                    os.environ.pop(CONNECT_ENV, None)
                self._exported = None
