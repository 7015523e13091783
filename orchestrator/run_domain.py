"""The ROS domain of a run: its own unless the user pins one, and never two runs on one.

cosim-orchestrate leases a domain id of this machine (``orchestrator.domains``) unless
``--domain`` or an explicitly set ``ROS_DOMAIN_ID`` pins one, and keeps discovery on this
machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) unless that variable is set. Every
multi-process run also claims its domain for as long as it goes: a held ``flock`` on
``$TMPDIR/cosim-ros-domains/<id>.run`` whose text says which run holds it, so that a second
run pinned to the same domain is refused at start, naming the first (two runs on one domain
hear each other's topics and both stop). The claim's second line is what a tool needs to join
the run (its ROS_DOMAIN_ID and discovery range): ``cosim-ros2`` reads it (``going``) to find
a run by itself.
"""

from __future__ import annotations

import fcntl
import os
import shlex
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

VALID = (range(0, 102), range(215, 233))
"""ROS 2 domain ids usable on Linux (others clash with the port ranges of ephemeral ports)."""
LEASE_WAIT_S = 30.0  # an unpinned run waits this long for a domain id when all are taken
RANGE_VAR = "ROS_AUTOMATIC_DISCOVERY_RANGE"

_claims: dict[int, object] = {}  # domain -> the open, locked .run file of this process
_whats: dict[int, str] = {}  # domain -> how its run is named


class DomainInUse(RuntimeError):
    """Another cosim run is going on the domain this run is pinned to."""


@dataclass
class RunDomain:
    """The domain a run uses, whether the user pinned it, and what pinned it."""

    domain: int
    pinned_by: str | None  # '--domain', 'ROS_DOMAIN_ID' or None (leased: the run's own)
    local_only: bool

    def lines(self, transport: str) -> list[str]:
        """What the command prints about it: a line that says which domain, then (over ROS 2)
        the commands that list its topics from another shell, each to paste as it is."""
        how = (f"pinned by {self.pinned_by}" if self.pinned_by
               else "this run's own; pin one with --domain N or ROS_DOMAIN_ID=N")
        where = ("discovery on this machine only" if self.local_only
                 else f"discovery range {os.environ.get(RANGE_VAR, 'SUBNET')}")
        head = f"ROS domain {self.domain} ({how}; {where})"
        if transport != "ros2":
            return [head]
        env = tool_environment(self.domain)
        return [f"{head}; its topics from another shell:",
                f"{env} {tool_command('cosim-ros2')} topic list", f"{env} ros2 topic list"]


def tool_environment(domain: int) -> str:
    """The variables a ROS 2 tool in another shell needs to join a run on ``domain`` of this
    process: its domain and discovery range (a tool on the default range, SUBNET, does not
    always find a LOCALHOST run)."""
    chosen = {RANGE_VAR: "LOCALHOST" if widened() else os.environ.get(RANGE_VAR),
              "ROS_LOCALHOST_ONLY": os.environ.get("ROS_LOCALHOST_ONLY")}
    parts = [f"{name}={shlex.quote(value)}" for name, value in chosen.items() if value]
    return " ".join([*parts, f"ROS_DOMAIN_ID={domain}"])


def tool_command(name: str) -> str:
    """How a user's shell starts cosim's command ``name``: by its name when it is on PATH,
    else the path of the one installed beside this Python (``.venv/bin/cosim-ros2``)."""
    if shutil.which(name):
        return name
    beside = Path(sys.executable).parent / name
    if not beside.exists():
        return name
    try:
        return shlex.quote(str(beside.absolute().relative_to(Path.cwd())))
    except ValueError:
        return shlex.quote(str(beside.absolute()))


def parse_domain(text: str, source: str) -> int:
    """A domain id from ``--domain`` or ``ROS_DOMAIN_ID``; ValueError naming the fix."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not any(value in r for r in VALID):
        raise ValueError(f"{source}={text!r}: expected a ROS domain id, 0..101 or 215..232 "
                         "(or leave it out: the run takes a free one of its own)")
    return value


def choose(pinned: int | None, what: str) -> RunDomain:
    """Decide the run's domain and set ROS_DOMAIN_ID (and the discovery range) for this
    process and every node it starts; claim it (DomainInUse if another run has it).
    ``pinned``: --domain's value; ``what``: how the holder is named to a second run."""
    pinned_by = "--domain" if pinned is not None else None
    env = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if pinned is None and env:
        pinned, pinned_by = parse_domain(env, "ROS_DOMAIN_ID"), "ROS_DOMAIN_ID"
    local_only = RANGE_VAR not in os.environ and "ROS_LOCALHOST_ONLY" not in os.environ
    if local_only:
        os.environ[RANGE_VAR] = "LOCALHOST"
    if pinned is not None:
        claim(pinned, what)
        domain = pinned
    else:
        domain = _lease_and_claim(what)
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    return RunDomain(domain, pinned_by, local_only)


def _lease_and_claim(what: str) -> int:
    """A leased domain (held until this process ends) that no run claims."""
    from orchestrator.domains import DomainLease

    deadline = time.monotonic() + LEASE_WAIT_S
    while True:
        lease = DomainLease(wait_s=max(deadline - time.monotonic(), 0.0))
        domain = lease.__enter__()  # held until this process ends, like the twin's
        try:
            claim(domain, what)
            _claims[domain] = (_claims[domain], lease)
            return domain
        except DomainInUse:  # a pinned run without a lease: try the next id
            lease.__exit__(None, None, None)
            if time.monotonic() >= deadline:
                raise


def claim(domain: int, what: str) -> None:
    """Mark ``domain`` as this process's run's (idempotent); DomainInUse naming the run that
    has it. Held until ``release`` or this process's end, however it ends."""
    if domain in _claims:
        return
    folder = Path(tempfile.gettempdir()) / "cosim-ros-domains"
    folder.mkdir(exist_ok=True)
    handle = open(folder / f"{domain}.run", "a+")  # noqa: SIM115 - held while the run goes
    if not _lock_now(handle):
        handle.seek(0)
        holder = handle.readline().strip() or "a cosim run starting"
        handle.close()
        raise DomainInUse(f"ROS domain {domain} is in use by another cosim run: {holder}. "
                          "Two runs on one domain hear each other's topics and both stop: "
                          "leave ROS_DOMAIN_ID unset and give no --domain (each run takes a "
                          "free domain of its own), or pin another one") from None
    _claims[domain], _whats[domain] = handle, what
    _write(handle, what)


def _lock_now(handle) -> bool:
    """Take ``handle``'s exclusive flock without waiting on a run that holds it; a few quick
    tries, since a tool looking for runs (``going``) may hold it shared for an instant."""
    for attempt in range(3):
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except OSError:
            if attempt < 2:
                time.sleep(0.02)
    return False


def leased_here() -> int | None:
    """The domain this process leased for its run (not pinned), if any."""
    return next((d for d, held in _claims.items() if isinstance(held, tuple)), None)


def claimed(domain: int) -> bool:
    """Whether this process holds ``domain``'s claim."""
    return domain in _claims


def describe(more: str) -> None:
    """Add ``more`` (the run directory) to what this process's claims say of its run."""
    for domain, held in _claims.items():
        _write(held[0] if isinstance(held, tuple) else held, f"{_whats[domain]}, {more}")


def _write(handle, what: str) -> None:
    domain = int(Path(handle.name).stem)
    handle.seek(0)
    handle.truncate()
    handle.write(f"{what} (pid {os.getpid()}, since {time.strftime('%H:%M:%S')})\n"
                 f"{tool_environment(domain)}\n")
    handle.flush()


@dataclass
class Claim:
    """A cosim run going on this machine, as its claim says: its domain, who holds it (the
    command, process id and run directory), what a tool needs to join it, and since when."""

    domain: int
    holder: str
    environment: dict[str, str]
    since: float  # when the claim was last written (the run started or named its directory)


def going() -> list[Claim]:
    """The runs going on this machine (their claims held by another process), newest first."""
    folder = Path(tempfile.gettempdir()) / "cosim-ros-domains"
    held = _held_files()
    claims = []
    for path in folder.glob("*.run"):
        try:
            stat = path.stat()
            if not path.stem.isdigit() or int(path.stem) in _claims:
                continue
            if held is not None and stat.st_ino not in held:
                continue
            if held is None and not _locked(path):
                continue
            first, _, rest = path.read_text().partition("\n")
        except OSError:
            continue
        env = dict(part.split("=", 1) for part in rest.split() if "=" in part)
        env.setdefault("ROS_DOMAIN_ID", path.stem)
        claims.append(Claim(int(path.stem), first.strip() or "a cosim run starting", env,
                            stat.st_mtime))
    return sorted(claims, key=lambda c: c.since, reverse=True)


def _held_files() -> set[int] | None:
    """The inode of every file with a flock held, from /proc/locks (None: unreadable). Inodes
    only: the device /proc/locks names is the superblock's, which stat() does not give on
    every file system (btrfs subvolumes, overlays)."""
    try:
        text = Path("/proc/locks").read_text()
    except OSError:
        return None
    held = set()
    for line in text.splitlines():
        fields = line.split()
        if "->" in fields or len(fields) < 6 or fields[1] != "FLOCK":
            continue  # a waiter, or another kind of lock
        held.add(int(fields[5].rsplit(":", 1)[1]))
    return held


def _locked(path: Path) -> bool:
    """Whether another process holds ``path``'s flock (where /proc/locks cannot say)."""
    with open(path) as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            return True
        fcntl.flock(handle, fcntl.LOCK_UN)
        return False


def release(domain: int) -> None:
    """Give the claim (and a lease taken with it) back."""
    held = _claims.pop(domain, None)
    _whats.pop(domain, None)
    for item in held if isinstance(held, tuple) else (held,):
        if item is None:
            continue
        if hasattr(item, "__exit__") and not hasattr(item, "read"):
            item.__exit__(None, None, None)
        else:
            item.close()


LOCALHOST_PEERS = 32
"""Participants that ROS 2's LOCALHOST discovery reaches on one domain (rmw_fastrtps probes
the ports of participant ids 0..31 on 127.0.0.1; two participants both above that never meet)."""
PROFILES = f"cosim-dds-profiles-{os.getuid()}"  # widen_discovery's, this user's, in $TMPDIR


def widened() -> bool:
    """Whether this process runs on widen_discovery's profile (a tool joining its run sets
    LOCALHOST, not the SYSTEM_DEFAULT the profile is used with)."""
    profile = Path(os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE", ""))
    return os.environ.get(RANGE_VAR) == "SYSTEM_DEFAULT" and profile.parent.name == PROFILES


def widen_discovery(participants: int) -> str | None:
    """Keep a run of ``participants`` DDS participants (its processes and the orchestrator's)
    discoverable under LOCALHOST discovery when they outnumber what LOCALHOST reaches: a
    Fast DDS profile that sets up what rmw_fastrtps does for LOCALHOST, probing ports for
    ``participants`` + 32 ids (at most 120, RTPS's per-domain ports), used through
    ``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT`` by this process and every process it
    starts. What was done, for the log; None when nothing needed doing. Only before this
    process loads rclpy (Fast DDS reads its profile once) and when the user chose no profile."""
    if os.environ.get(RANGE_VAR) != "LOCALHOST" or participants <= LOCALHOST_PEERS - 4:
        return None
    import runtime.transport  # not .ros2: it loads rclpy, after which the profile is read

    folder = Path(runtime.transport.__file__).parent
    users = [os.environ.get(v) for v in ("FASTRTPS_DEFAULT_PROFILES_FILE",
                                         "FASTDDS_DEFAULT_PROFILES_FILE")]
    # cosim's own default profile (which a parent that imported the transport passes on) is
    # no choice of the user's
    ours = str(folder / "fastdds_profile.xml")
    if "rclpy._rclpy_pybind11" in sys.modules or any(u and u != ours for u in users):
        return (f"{participants} DDS participants on one domain with LOCALHOST discovery, "
                f"which reaches {LOCALHOST_PEERS}: some may never discover each other. Pack "
                "nodes into fewer processes (--pack kind) or leave the Fast DDS profile to "
                "cosim.")
    peers = min(120, participants + LOCALHOST_PEERS)
    template = (folder / "fastdds_localhost_profile.xml").read_text()
    profiles = Path(tempfile.gettempdir()) / PROFILES
    profiles.mkdir(exist_ok=True)
    path = profiles / f"localhost-{peers}.xml"
    if not path.exists():
        staged = profiles / f".{path.name}.{os.getpid()}"
        staged.write_text(template.replace("{peers}", str(peers)))
        staged.replace(path)
    os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(path)
    os.environ[RANGE_VAR] = "SYSTEM_DEFAULT"
    return (f"{participants} DDS participants: LOCALHOST discovery widened to {peers} "
            f"participant ports ({path})")
