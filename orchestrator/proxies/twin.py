"""A digital twin's link to the real robot: a rosbridge v2 client in a thread of its own.

What the robot publishes on the ``subscribe`` topics enters the run through the external
node (``TwinArrivals``: at the next tick, recorded, so the session replays); what the run
publishes on the ``publish`` topics goes back to the robot, the latest message per topic
(an unsent one is replaced, never queued). Nothing the network does blocks the tick loop:
the loop only puts into and takes from memory. The link says what it sees (connected,
lost, stale, back) on stderr and in the log, and keeps per robot topic the delay from the
message's stamp to its arrival, the wait from arrival to the tick it entered at, the
mirror delay (stamp to the tick it entered: what the twin lags the robot by), losses
(gaps in the stamps against the stream's mean period) and stale periods, for the manifest
and the summary.

Stamps and the clock: a real robot stamps with its own clock. When stamps are within a
minute of this machine's clock the two are taken as shared and the delay is arrival minus
stamp; otherwise (a simulated stand-in stamps from zero) the offset is unknown and the delay
is measured above the fastest message seen (``clock: offset``), which is the network's and
the robot's jitter, not the absolute delay (per connection: a restarted robot may stamp
from a new origin).
"""

from __future__ import annotations

import json
import logging
import os
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from plan.options import RunOptions
from plan.roles import NodeRole
from plan.scenario import Scenario
from plan.twin import TwinAddress, parse_twin_url
from runtime.arrivals import Arrivals

log = logging.getLogger("cosim")

POLL_S = 0.02  # how long the link waits for a frame before it looks at what to send
FIRST_RETRY_S = 0.25
SHARED_CLOCK_S = 60.0  # stamps this close to the wall clock: the robot's clock is ours
MAX_SAMPLES = 100_000  # delays kept per topic for the percentiles


def twin_address(scenario: Scenario, options: RunOptions, external: Any) -> TwinAddress | None:
    """The robot to connect to: ``--twin`` or the scenario's ``twin.url``; None when the run
    is no twin or is fed recorded inputs (a replay connects to nothing)."""
    spec = scenario.model.twin
    if spec is None or not (external is None or isinstance(external, Arrivals)):
        return None
    text = options.twin or spec.url
    return parse_twin_url(text) if text else None


def say(line: str) -> None:
    """What the link tells the user: stderr (live) and the run's log."""
    print(f"cosim-orchestrate: twin: {line}", file=sys.stderr, flush=True)
    log.info("twin: %s", line)


class Percentiles:
    """Samples in ms, summarised as count, p50, p99 and max."""

    def __init__(self) -> None:
        self.samples: list[float] = []

    def add(self, value_ms: float) -> None:
        """One sample."""
        if len(self.samples) < MAX_SAMPLES:
            self.samples.append(value_ms)

    def summary(self) -> dict[str, float] | None:
        """{n, p50_ms, p99_ms, max_ms}; None without samples."""
        if not self.samples:
            return None
        s = sorted(self.samples)
        pick = lambda q: round(s[min(len(s) - 1, int(q * len(s)))], 3)  # noqa: E731
        return {"n": len(s), "p50_ms": pick(0.5), "p99_ms": pick(0.99), "max_ms": round(s[-1], 3)}


class TopicStats:
    """What one robot topic did: arrivals, delays, losses, stale periods."""

    def __init__(self, robot: str, run: str, stale_after_s: float):
        self.robot, self.run, self.stale_after_s = robot, run, stale_after_s
        self.arrived = 0
        self.entered = 0
        self.superseded = 0  # arrived, then replaced by a newer one before a tick took it
        self.refused = 0  # did not convert to the run's type
        self.delay = Percentiles()
        self.entry_wait = Percentiles()
        # arrival - stamp (s) per connection: a restarted robot may stamp from a new origin
        self.sessions: list[list[float]] = [[]]
        self.mirror_sessions: list[list[float]] = [[]]  # entry - stamp (s): the mirror's lag
        self.last_stamp: float | None = None
        self.gaps: list[float] = []
        self.lost = 0
        self.last_arrival: float | None = None  # monotonic
        self.stale_since: float | None = None
        self.stale_periods = 0
        self.stale_s = 0.0

    def arrival(self, now: float, wall: float, stamp: float | None) -> float | None:
        """A message arrived (``now`` monotonic, ``wall`` epoch, ``stamp`` the header's, s);
        the time it was stale for, when it ends a stale period."""
        self.arrived += 1
        back = None
        if self.stale_since is not None:
            back = now - self.stale_since
            self.stale_s += back
            self.stale_since = None
        self.last_arrival = now
        if stamp is not None and stamp > 0:
            self.sessions[-1].append(wall - stamp)
            if self.last_stamp is not None and stamp > self.last_stamp:
                gap = stamp - self.last_stamp
                if len(self.gaps) >= 5:  # the stream's period: the mean gap (bursts cancel)
                    period = sum(self.gaps) / len(self.gaps)
                    if gap > 1.5 * period:
                        self.lost += round(gap / period) - 1
                self.gaps = (self.gaps + [gap])[-50:]
            self.last_stamp = stamp
        return back

    def new_connection(self) -> None:
        """The link connected again: stamps may start over (a restarted robot)."""
        if self.sessions[-1]:
            self.sessions.append([])
            self.mirror_sessions.append([])
        self.last_stamp = None

    def check_stale(self, now: float) -> bool:
        """Whether the topic just went stale."""
        if (self.last_arrival is not None and self.stale_since is None
                and now - self.last_arrival > self.stale_after_s):
            self.stale_since = self.last_arrival + self.stale_after_s
            self.stale_periods += 1
            return True
        return False

    def summary(self, now: float) -> dict[str, Any]:
        """The manifest's entry for this topic."""
        raw = [d for session in self.sessions for d in session]
        clock = "shared" if raw and abs(sorted(raw)[len(raw) // 2]) < SHARED_CLOCK_S else "offset"
        delay, mirror = Percentiles(), Percentiles()
        for session, lags in zip(self.sessions, self.mirror_sessions, strict=True):
            offset = 0.0 if clock == "shared" or not session else min(session)
            for value in session:
                delay.add((value - offset) * 1e3)
            for value in lags:
                mirror.add((value - offset) * 1e3)
        stale_s = self.stale_s + (now - self.stale_since if self.stale_since else 0.0)
        return {"as": self.run, "arrived": self.arrived, "entered": self.entered,
                "superseded": self.superseded, "refused": self.refused, "lost": self.lost,
                "clock": clock, "delay": delay.summary(), "entry_wait": self.entry_wait.summary(),
                "mirror_delay": mirror.summary(),
                "stale_periods": self.stale_periods, "stale_s": round(stale_s, 3),
                "stale_at_end": self.stale_since is not None,
                "never_arrived": self.arrived == 0}


class TwinArrivals(Arrivals):
    """The run's arrivals, which also time each robot message from arrival to entry."""

    def __init__(self, topics: dict[str, type]):
        super().__init__(topics)
        self.link: TwinLink | None = None
        self._since: dict[str, float] = {}
        self.stats: dict[str, TopicStats] = {}  # run topic -> its robot topic's stats

    def put(self, topic: str, msg: Any) -> None:
        """A message arrived (from the robot, or from another client of the run)."""
        super().put(topic, msg)
        with self._lock:
            if topic in self._since and topic in self.stats:
                self.stats[topic].superseded += 1
            self._since[topic] = time.monotonic()

    def take(self, tick: int | None = None) -> dict[str, Any]:
        """What arrived since the last take; each robot message's wait is recorded."""
        now = time.monotonic()
        with self._lock:
            taken, self._waiting = self._waiting, {}
            since, self._since = self._since, {}
        wall = time.time()
        for topic, msg in taken.items():
            stats = self.stats.get(topic)
            if stats is not None and topic in since:
                stats.entered += 1
                stats.entry_wait.add((now - since[topic]) * 1e3)
                stamp = _stamp_s(msg)
                if stamp:
                    stats.mirror_sessions[-1].append(wall - stamp)
        return taken


class Pacer:
    """Paces the tick loop on the wall clock: tick k is decided no earlier than k + 1 ticks
    after tick 0 was; a loop that falls behind goes on from where it is (no burst)."""

    def __init__(self, tick_ns: int, then: Callable[[int], None] | None):
        self.tick_s = tick_ns / 1e9
        self.then = then
        self.origin: float | None = None
        self.behind = 0  # ticks decided more than a tick late

    def __call__(self, k: int) -> None:
        """Tick ``k`` was decided: pass it on, then wait for its time on the wall clock."""
        if self.then is not None:
            self.then(k)
        now = time.monotonic()
        if self.origin is None:
            self.origin = now - self.tick_s * (k + 1)
        due = self.origin + self.tick_s * (k + 1)
        if due > now:
            time.sleep(due - now)
        elif now - due > self.tick_s:
            self.behind += 1
            self.origin = now - self.tick_s * (k + 1)


class TwinLink:
    """The rosbridge client: one thread, reconnecting with backoff until closed."""

    def __init__(self, scenario: Scenario, address: TwinAddress, arrivals: TwinArrivals):
        spec = scenario.model.twin
        self.address = address
        self.port = address.port  # for LiveEndpoints.close: this sink ran
        self.arrivals = arrivals
        self.subscribe = dict(spec.subscribe)  # robot -> run
        self.classes = {robot: arrivals.topics[run] for robot, run in self.subscribe.items()}
        self.publish = dict(spec.publish)  # run -> robot
        self.out_classes = {run: scenario.topics[run] for run in self.publish}
        self.reconnect_max_s = spec.reconnect_max / 1e9
        self.topic_stats = {robot: TopicStats(robot, run, spec.stale_after / 1e9)
                            for robot, run in self.subscribe.items()}
        arrivals.stats = {s.run: s for s in self.topic_stats.values()}
        self._out: dict[str, bytes] = {}
        self._out_lock = threading.Lock()
        self.sent = dict.fromkeys(self.publish.values(), 0)
        self.replaced = 0  # outgoing messages replaced by a newer one before they were sent
        self.connects = 0
        self.attempts = 0
        self.errors: dict[str, int] = {}  # the robot's status messages, counted
        self.connected_s = 0.0
        self.started = time.monotonic()
        self.pacer: Pacer | None = None
        self.domain: int | None = None  # the run's own ROS domain (own_domain)
        self._lease = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="cosim-twin", daemon=True)

    def own_domain(self) -> None:
        """Take a ROS domain no other run here uses, for this run's processes: the robot (or
        a stand-in on this machine) publishes the same topic names on its own domain, and
        reaches the twin through rosbridge only."""
        from orchestrator.domains import DomainLease
        from orchestrator.run_domain import leased_here

        if (own := leased_here()) is not None:  # cosim-orchestrate took one already
            self.domain = own
            return
        lease = DomainLease(wait_s=10.0)
        try:
            self.domain = lease.__enter__()  # held until this process ends
        except Exception as exc:  # noqa: BLE001 - the twin still works, only less isolated
            say(f"could not take a ROS domain of its own ({exc}); the run stays on "
                f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')}, where a robot on this "
                "machine would mix its topics with the run's")
            return
        self._lease = lease
        os.environ["ROS_DOMAIN_ID"] = str(self.domain)

    def start(self) -> list[str]:
        """Start connecting (in the background); the lines that say to where."""
        self._thread.start()
        domain = ([f"the twin's own ROS 2 topics are on domain {self.domain} "
                   f"(ROS_DOMAIN_ID={self.domain} ros2 topic list)"]
                  if self.domain is not None else [])
        return domain + [f"twin of the robot at {self.address.url}: "
                + ", ".join(f"{r} -> {t}" for r, t in self.subscribe.items())
                + ("; back: " + ", ".join(f"{t} -> {r}" for t, r in self.publish.items())
                   if self.publish else "")]

    def offer(self, topic: str, data: bytes) -> None:
        """A message of the run: kept for the robot when its topic goes back (never blocks)."""
        if topic in self.publish:
            with self._out_lock:
                if topic in self._out:
                    self.replaced += 1
                self._out[topic] = data

    def close(self) -> None:
        """Stop the link (the run is over)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5)

    def stats_entry(self) -> dict[str, Any]:
        """The manifest's ``live.twin``: the link's and every topic's network figures."""
        now = time.monotonic()
        return {"url": self.address.url, "connects": self.connects,
                "reconnects": max(self.connects - 1, 0), "attempts": self.attempts,
                "connected_s": round(self.connected_s, 3),
                "topics": {robot: s.summary(now) for robot, s in self.topic_stats.items()},
                "ros_domain": self.domain,
                "sent": self.sent, "replaced_before_sending": self.replaced,
                "robot_errors": self.errors,
                "ticks_behind_wall_clock": self.pacer.behind if self.pacer else None}

    def stats(self) -> dict[str, Any]:
        """LiveEndpoints' name for ``stats_entry``."""
        return self.stats_entry()

    # -- the thread ----------------------------------------------------------------------

    def _run(self) -> None:
        from websockets.exceptions import WebSocketException
        from websockets.sync.client import connect

        wait = FIRST_RETRY_S
        lost_at: float | None = time.monotonic()  # since when the robot is not reached
        failed = 0  # tries since the last connection
        while not self._stop.is_set():
            self.attempts += 1
            try:
                ws = connect(self.address.url, open_timeout=2.0, close_timeout=1.0,
                             max_size=64 * 2**20)
            except (OSError, TimeoutError, WebSocketException) as exc:
                failed += 1
                if failed == 1 or failed % 10 == 0:
                    say(f"no robot at {self.address.url} ({_reason(exc)}); trying again with "
                        f"backoff up to {self.reconnect_max_s:g} s, the run goes on"
                        + (f" (try {failed})" if failed > 1 else ""))
                self._stop.wait(wait)
                wait = min(wait * 2, self.reconnect_max_s)
                continue
            self.connects += 1
            after = (f" after {time.monotonic() - lost_at:.1f} s and {failed + 1} tries"
                     if failed else "")
            say(f"{'connected' if self.connects == 1 else 'reconnected'} to the robot at "
                f"{self.address.url}{after}")
            lost_at, wait, failed = None, FIRST_RETRY_S, 0
            for stats in self.topic_stats.values():
                stats.new_connection()
            since = time.monotonic()
            try:
                self._session(ws)
            except Exception as exc:  # noqa: BLE001 - whatever ends a session, the link goes on
                lost_at = time.monotonic()
                say(f"lost the robot at {self.address.url} ({_reason(exc)}); reconnecting")
            finally:
                self.connected_s += time.monotonic() - since
                ws.close()

    def _session(self, ws) -> None:
        """Subscribe and advertise, then serve until the connection or the run ends."""
        from plan.ros_types import ros_type

        for robot, cls in self.classes.items():
            ws.send(json.dumps({"op": "subscribe", "id": f"cosim_twin:{robot}", "topic": robot,
                                "type": ros_type(cls)}))
        for run, robot in self.publish.items():
            ws.send(json.dumps({"op": "advertise", "id": f"cosim_twin:{robot}", "topic": robot,
                                "type": ros_type(self.out_classes[run])}))
        while not self._stop.is_set():
            try:
                frame = ws.recv(timeout=POLL_S)
            except TimeoutError:
                frame = None
            if frame is not None:
                self._frame(frame)
            self._check_stale()
            self._send_pending(ws)

    def _frame(self, frame: str | bytes) -> None:
        """One frame from the robot."""
        try:
            request = json.loads(frame)
        except ValueError:
            return
        op = request.get("op")
        if op == "publish":
            self._arrived(request.get("topic"), request.get("msg"))
        elif op == "status" and request.get("level") in ("error", "warning"):
            text = str(request.get("msg"))
            if text not in self.errors:
                say(f"the robot says: {text}")
            self.errors[text] = self.errors.get(text, 0) + 1

    def _arrived(self, robot: str, body: Any) -> None:
        from runtime.live.convert import MessageError, from_json

        now, wall = time.monotonic(), time.time()
        stats = self.topic_stats.get(robot)
        if stats is None:
            return
        try:
            msg = from_json(self.classes[robot], body, robot)
        except MessageError as exc:
            if not stats.refused:
                say(f"{robot} does not fit {stats.run}'s type: {exc}")
            stats.refused += 1
            return
        back = stats.arrival(now, wall, _stamp_s(msg))
        if back is not None:
            say(f"{robot} is back after {back:.2f} s without messages")
        self.arrivals.put(stats.run, msg)

    def _check_stale(self) -> None:
        now = time.monotonic()
        for robot, stats in self.topic_stats.items():
            if stats.check_stale(now):
                say(f"{robot} is stale: nothing for {stats.stale_after_s:g} s (the twin "
                    f"holds its last {stats.run})")

    def _send_pending(self, ws) -> None:
        from runtime.cdr.decode import decode
        from runtime.live.convert import to_json

        with self._out_lock:
            pending, self._out = self._out, {}
        for topic, data in sorted(pending.items()):
            robot = self.publish[topic]
            body = to_json(decode(data, self.out_classes[topic]))
            ws.send(json.dumps({"op": "publish", "topic": robot, "msg": body},
                               separators=(",", ":")))
            self.sent[robot] += 1


def _stamp_s(msg: Any) -> float | None:
    """A message's header stamp in seconds (None without a header)."""
    header = getattr(msg, "header", None)
    return header.stamp.sec + header.stamp.nanosec / 1e9 if header is not None else None


def _reason(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    return text.splitlines()[0][:200]


def never_reached(external: Any) -> str | None:
    """Why a live twin run failed when its robot never answered (the link never connected:
    nothing of the robot entered the run), else None. Such a run is no twin of anything."""
    link = getattr(external, "link", None) if isinstance(external, TwinArrivals) else None
    if link is None or link.connects:
        return None
    return (f"twin: the robot at {link.address.url} never answered ({link.attempts} "
            f"attempt(s) to connect over {time.monotonic() - link.started:.1f} s): nothing of "
            "it entered the run, so the run is no twin. Start the robot's rosbridge server "
            "(or a stand-in: cosim-node physics --scenario scenarios/nav.yaml --realtime "
            "--rosbridge HOST:PORT) and give its address with --twin ws://HOST:PORT")


def twin_run(scenario: Scenario, options: RunOptions, on_tick: Callable[[int], None] | None,
             external: Any) -> tuple[TwinArrivals, RunOptions, Callable[[int], None]]:
    """What a live twin run changes: its arrivals (with the link to the robot, started with
    the run's live endpoints), strict lockstep (tick k starts when k - 1 is decided, so what
    arrived enters at the tick whose wall time it arrived before) and a loop paced on the
    wall clock (real time, whatever ``real_time_factor`` says)."""
    external_plan = next(p for p in scenario.nodes.values()
                         if p.role is NodeRole.ORCHESTRATOR)
    arrivals = TwinArrivals(external_plan.outputs)
    arrivals.link = TwinLink(scenario, twin_address(scenario, options, external), arrivals)
    pacer = Pacer(scenario.tick_ns, on_tick)
    arrivals.link.pacer = pacer
    if scenario.model.transport == "ros2" and not options.in_process:
        arrivals.link.own_domain()
    # the robot's wall clock paces a live twin (real time): a --real-time-factor gives way
    return arrivals, options.with_(pipeline=False, real_time_factor=None), pacer
