"""Where a server of a run listens: ``ADDR:PORT`` text, checked, and whether it is loopback.

``--live`` and ``--rosbridge`` take an optional ``ADDR:PORT``; a bare port or a bare address
fills in the other half from the default (``127.0.0.1`` and the server's usual port). Port 0
asks the system for a free port (the run prints the one it got).
"""

from __future__ import annotations

import ipaddress
import socket
from dataclasses import dataclass

LIVE_DEFAULT = "127.0.0.1:8765"
"""Foxglove's usual WebSocket address."""
ROSBRIDGE_DEFAULT = "127.0.0.1:9090"
"""rosbridge_server's usual address."""


@dataclass(frozen=True)
class ListenAddress:
    """A host and a TCP port to listen on."""

    host: str
    port: int

    def __str__(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{host}:{self.port}"

    @property
    def loopback(self) -> bool:
        """Whether only this machine can connect ('localhost' and 127.0.0.0/8, ::1)."""
        if self.host == "localhost":
            return True
        try:
            return ipaddress.ip_address(self.host).is_loopback
        except ValueError:
            return False


def parse_listen(text: str, default: str) -> ListenAddress:
    """``'ADDR:PORT'``, ``'PORT'`` or ``'ADDR'`` -> ListenAddress; ValueError saying what fits."""
    base_host, _, base_port = default.rpartition(":")
    value = text.strip()
    if value.startswith("[") and "]" in value:  # [::1]:9090
        host, _, rest = value[1:].partition("]")
        port = rest.lstrip(":") or base_port
    elif value.count(":") == 1:
        host, port = value.split(":")
        host = host or base_host
    elif value.isdigit():
        host, port = base_host, value
    else:
        host, port = value or base_host, base_port
    if not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"{text!r} is not ADDR:PORT: the port must be a number from 0 to "
                         f"65535 (e.g. {default}; port 0 picks a free one)")
    if host != "localhost":
        try:
            ipaddress.ip_address(host)
        except ValueError:
            raise ValueError(f"{text!r} is not ADDR:PORT: {host!r} is not an IP address "
                             f"(e.g. {default}, or 0.0.0.0:{port} for every interface)") from None
    return ListenAddress(host, int(port))


def port_problem(address: ListenAddress) -> str | None:
    """Why nothing could listen on ``address`` now (taken, not this machine's), or None."""
    if address.port == 0:
        return None
    family = socket.AF_INET6 if ":" in address.host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((address.host, address.port))
        except OSError as exc:
            return exc.strerror or str(exc)
    return None


def exposure_warning(what: str, address: ListenAddress) -> str | None:
    """The warning for a server reachable from other machines, or None on loopback."""
    if address.loopback:
        return None
    return (f"{what} listens on {address}, reachable from other machines, and has no "
            f"authentication: anyone who can connect can watch the run and drive it. Use a "
            f"loopback address (127.0.0.1) unless this network is trusted.")


def exposure_warnings(live: ListenAddress | None, rosbridge: ListenAddress | None) -> list[str]:
    """The warnings for the live view and rosbridge addresses that are not loopback."""
    found = [exposure_warning("the live view (--live)", live) if live else None,
             exposure_warning("rosbridge (--rosbridge)", rosbridge) if rosbridge else None]
    return [w for w in found if w]


def address_problems(live: ListenAddress | None, rosbridge: ListenAddress | None) -> list[str]:
    """Why the live view or rosbridge could not listen where asked (checked before a run
    starts anything), each naming the option and the fix."""
    out = []
    for flag, address in (("--live", live), ("--rosbridge", rosbridge)):
        if address is None:
            continue
        problem = port_problem(address)
        if problem:
            out.append(f"{flag} {address}: cannot listen there ({problem}); give another "
                       f"ADDR:PORT (port 0 picks a free one)")
    if live and rosbridge and live.port == rosbridge.port != 0 and live.host == rosbridge.host:
        out.append(f"--live and --rosbridge both ask for {live}; give them different ports")
    return out
