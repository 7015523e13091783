"""ROS 2 domain ids leased per machine, so that runs side by side never hear each other.

ROS 2 offers about a hundred usable domain ids on one host (each takes a range of UDP
ports). A lease is a held ``flock`` on ``$TMPDIR/cosim-ros-domains/<id>.lock``: it is
released when the holder closes it or dies, however it dies, so a crashed run never keeps
its id. The pytest plugin leases one per test, ``cosim-sweep`` one per multi-process run.
"""

from __future__ import annotations

import fcntl
import os
import random
import tempfile
import time
from pathlib import Path

DOMAINS = range(1, 102)
"""ROS 2 domain ids handed out (0 is everyone's default; above 101 clashes with ports)."""
RETRY_S = 0.25


class DomainLease:
    """A ROS domain id no other test, sweep run or session on this machine uses while held.

    A held flock on <tmp>/cosim-ros-domains/<id>.lock reserves it among cosim processes; an
    id in the environment of any running process we can see is skipped too. Successive
    leases of one process take successive ids, so each test of a session has its own.
    ``wait_s``: how long to wait for an id to come free when all are taken (default: fail
    at once).
    """

    _order: list[int] = []

    def __init__(self, wait_s: float = 0.0) -> None:
        self.domain: int | None = None
        self.wait_s = wait_s
        self._file = None

    def __enter__(self) -> int:
        deadline = time.monotonic() + self.wait_s
        while True:
            domain = self._try_lease()
            if domain is not None:
                return domain
            if time.monotonic() >= deadline:
                raise RuntimeError(f"cosim: no free ROS domain id in "
                                   f"{DOMAINS.start}..{DOMAINS.stop - 1}")
            time.sleep(RETRY_S)

    def _try_lease(self) -> int | None:
        """Lock the first free id in this process's order; None when every id is taken."""
        lock_dir = Path(tempfile.gettempdir()) / "cosim-ros-domains"
        lock_dir.mkdir(exist_ok=True)
        used = domains_in_use()
        if not DomainLease._order:
            DomainLease._order = list(DOMAINS)
            random.Random(os.getpid()).shuffle(DomainLease._order)
        ids = DomainLease._order
        for domain in (d for d in ids if d not in used):
            handle = open(lock_dir / f"{domain}.lock", "w")  # noqa: SIM115 - held until exit
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                handle.close()
                continue
            self.domain, self._file = domain, handle
            ids.remove(domain)
            ids.append(domain)
            return domain
        return None

    def __exit__(self, *exc: object) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


def domains_in_use() -> set[int]:
    """ROS_DOMAIN_ID values in the environment of the processes we can read (ours included)."""
    import psutil

    used = set()
    for proc in psutil.process_iter():
        try:
            value = proc.environ().get("ROS_DOMAIN_ID")
        except (psutil.Error, OSError):
            continue
        if value and value.isdigit():
            used.add(int(value))
    return used
