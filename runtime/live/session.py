"""Both live endpoints of one process, started and stopped together: the Foxglove live view
(``--live``) and the rosbridge server (``--rosbridge``), and any other sink of the run's
messages (a digital twin's link to its robot)."""

from __future__ import annotations

import logging
import threading
from typing import Any

from plan.listen import ListenAddress
from runtime.live.endpoints import Catalog

log = logging.getLogger("cosim")


class LiveError(RuntimeError):
    """An endpoint could not start (the address is taken or not this machine's)."""


class LiveEndpoints:
    """The endpoints a run asked for; ``offer`` feeds both and never blocks."""

    def __init__(self, catalog: Catalog, live: ListenAddress | None,
                 rosbridge: ListenAddress | None, name: str, end_ns: int | None = None,
                 control_later: bool = False, extra: dict[str, Any] | None = None):
        self.catalog = catalog
        self.control_later = control_later  # services come later (attach_services)
        if control_later:  # a client's call made before then waits for them
            catalog.services_ready = threading.Event()
        self.live_address = live
        self.rosbridge_address = rosbridge
        self.name = name
        self.end_ns = end_ns
        self.foxglove = None
        self.rosbridge = None
        self._sinks: list[Any] = []
        # other sinks (a twin's link): start() -> lines, offer(topic, data), close(), stats()
        self.extra = dict(extra or {})

    def start(self) -> list[str]:
        """Start the endpoints; the lines that say where they listen (and warnings)."""
        lines = []
        try:
            if self.live_address is not None:
                from runtime.live.foxglove_live import FoxgloveLive

                self.foxglove = FoxgloveLive(self.live_address, self.catalog, self.name,
                                             self.end_ns, self.control_later)
                port = _listen(self.foxglove, "the live view (--live)", self.live_address)
                lines.append(f"live view (Foxglove): ws://{_host(self.live_address)}:{port}")
            if self.rosbridge_address is not None:
                from runtime.live.rosbridge import RosbridgeServer

                self.rosbridge = RosbridgeServer(self.rosbridge_address, self.catalog)
                port = _listen(self.rosbridge, "rosbridge (--rosbridge)", self.rosbridge_address)
                lines.append(f"rosbridge: ws://{_host(self.rosbridge_address)}:{port}")
            for sink in self.extra.values():
                lines += sink.start()
        except BaseException:
            self.close()
            raise
        self._sinks = [s for s in (self.foxglove, self.rosbridge) if s is not None]
        self._sinks += list(self.extra.values())
        for line in lines:
            log.info("%s", line)
        return lines

    def attach_services(self, services, actions=None) -> None:
        """The services (and actions) clients may call, once they exist (the run's
        simulation control)."""
        self.catalog.services = services
        self.catalog.actions = actions
        if self.catalog.services_ready is not None:
            self.catalog.services_ready.set()
        if self.foxglove is not None and services is not None:
            self.foxglove.attach_services()

    def offer(self, topic: str, data: bytes) -> None:
        """A message of the run (CDR bytes), for whichever client wants it."""
        for sink in self._sinks:
            sink.offer(topic, data)

    def close(self) -> dict[str, Any]:
        """Stop both; what they did, for the manifest."""
        self._sinks = []
        if self.catalog.services_ready is not None:
            self.catalog.services_ready.set()  # calls still waiting for services: none come
        stats = {}
        for key, sink in (("foxglove", self.foxglove), ("rosbridge", self.rosbridge),
                          *self.extra.items()):
            if sink is None:
                continue
            try:
                sink.close()
            except Exception as exc:  # noqa: BLE001 - stopping must not hide the run's result
                log.warning("%s: stopping: %s", key, exc)
            if sink.port is not None:
                stats[key] = sink.stats()
        return stats


def _listen(server, what: str, address: ListenAddress) -> int:
    try:
        return server.start()
    except (OSError, RuntimeError) as exc:
        raise LiveError(f"{what} could not listen on {address}: {exc}") from exc


def _host(address: ListenAddress) -> str:
    return f"[{address.host}]" if ":" in address.host else address.host
