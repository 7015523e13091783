"""Fault injection: a seeded series of runs, each with one fault, each checked.

Faults, as trusted systems test them (SQLite fails every write and crashes mid-way; ros2
launch escalates SIGINT, SIGTERM, SIGKILL): a node killed or exiting at a random tick, the
orchestrator SIGKILLed at a random moment of start-up or of the tick loop, the disk filling
at a random size (a file-size limit, RLIMIT_FSIZE, on the run's processes), a stray
publisher appearing on a topic of the run, a client disconnecting in the middle of a
request. Each run is checked for: no process left (every process of a run carries a mark in
its environment), no hang (a deadline per run), the exit code documented for its fault,
and every tick before the fault readable (from the bag, or the parts where the orchestrator
died or the finish command where the disk was full): a tick missing there is a record lost.

    python -m bench.faults --runs 40 --seed 1

prints one line per run and the counts: runs, faults by kind, orphans, hangs, records lost,
wrong exit codes. The test suite runs a short series (tests/test_fault_injection.py).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import resource
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import psutil
import yaml

ROOT = Path(__file__).resolve().parent.parent
ORCHESTRATE = [sys.executable, "-m", "orchestrator.cosim_orchestrate"]
FINISH = [sys.executable, "-m", "orchestrator.outputs.finish"]
SELF = [sys.executable, "-m", "bench.faults"]
CHAIN = ROOT / "tests" / "scenarios" / "long_chain.yaml"
MARK = "COSIM_FAULT_RUN"  # every process of a run carries MARK=<its id>
KINDS = ("node_kill", "node_exit", "orchestrator_kill", "disk_full", "stray_publisher",
         "client_disconnect")
EXPECTED = {"node_kill": 3, "node_exit": 3, "orchestrator_kill": -9, "disk_full": 5,
            "stray_publisher": 3, "client_disconnect": 0}
"""The exit code documented for each fault (-9: the orchestrator itself was SIGKILLed)."""
HANG_S = 120.0  # a run that outlives this hangs
GONE_S = 20.0  # the processes of a finished (or killed) run are gone within this
PERIODS = {"/head": 1, "/middle": 1, "/tail": 2}  # long_chain: ticks per activation


@dataclass
class Fault:
    """One run's fault: its kind and where it strikes."""

    kind: str
    seed: int
    at: float  # a tick (node faults), seconds (kills, clients) or bytes (the disk)

    def describe(self) -> str:
        """'node_kill at tick 42'."""
        unit = {"disk_full": "bytes", "orchestrator_kill": "s", "client_disconnect": "s",
                "stray_publisher": "s"}.get(self.kind, "tick")
        at = f"{self.at:.2f}" if unit == "s" else str(int(self.at))
        return f"{self.kind} at {at} {unit}"


@dataclass
class Checked:
    """What one run left: exit code, hang, orphans, records lost, and what was wrong."""

    fault: Fault
    code: int | None = None
    hung: bool = False
    orphans: int = 0
    lost: int = 0
    problems: list[str] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        """Everything as documented."""
        return not self.problems


def plan(seed: int, runs: int, kinds: tuple[str, ...] = KINDS) -> list[Fault]:
    """The series: ``runs`` faults, the kinds in turn (each seen once before any twice),
    where each strikes drawn from ``seed``."""
    rng = random.Random(seed)
    faults = []
    for i in range(runs):
        kind = kinds[i % len(kinds)]
        at = {"node_kill": 2 * rng.randrange(5, 45), "node_exit": 2 * rng.randrange(5, 45),
              "orchestrator_kill": rng.uniform(0.0, 3.0),
              "disk_full": rng.randrange(12, 40) * 1024,
              "stray_publisher": rng.uniform(0.5, 2.0),
              "client_disconnect": rng.uniform(0.2, 1.5)}[kind]
        faults.append(Fault(kind, rng.randrange(1 << 30), at))
    return faults


def _scenario(fault: Fault, where: Path) -> Path:
    doc = yaml.safe_load(CHAIN.read_text())
    doc["seed"] = fault.seed % 1000
    # the faults that end a run must find it going: a long run (long_chain runs thousands
    # of ticks a second), which the fault stops
    doc["duration"] = {"orchestrator_kill": "600s", "disk_full": "600s",
                       "stray_publisher": "600s", "client_disconnect": "5s"}.get(fault.kind, "1s")
    if fault.kind in ("node_kill", "node_exit"):
        doc["nodes"][2].update(kind="faulty", params={
            "output": "/tail", "fail_at": int(fault.at),
            "mode": "kill" if fault.kind == "node_kill" else "exit"})
    path = where / "chain.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def _limit_files(size: int):
    def limit() -> None:  # in the orchestrator, before exec: its nodes inherit it
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))
    return limit


def marked(mark: str) -> list[psutil.Process]:
    """The live processes of the run ``mark``."""
    found = []
    for proc in psutil.process_iter():
        try:
            if proc.environ().get(MARK) == mark and proc.status() != psutil.STATUS_ZOMBIE:
                found.append(proc)
        except (psutil.Error, OSError):
            continue
    return found


def run_one(fault: Fault, where: Path) -> Checked:
    """Run one fault and check what it left."""
    from orchestrator.domains import DomainLease

    checked = Checked(fault)
    started = time.monotonic()
    where.mkdir(parents=True, exist_ok=True)
    scenario, out = _scenario(fault, where), where / "out"
    mark = uuid.uuid4().hex
    with DomainLease(wait_s=60) as domain:
        env = {**os.environ, MARK: mark, "ROS_DOMAIN_ID": str(domain)}
        args = ["--paused"] if fault.kind == "client_disconnect" else []
        extra = ({"preexec_fn": _limit_files(int(fault.at))} if fault.kind == "disk_full"
                 else {})
        proc = subprocess.Popen([*ORCHESTRATE, str(scenario), "--out", str(out), "--quiet",
                                 *args], cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True, **extra)
        helper = _inject(fault, proc, env)
        try:
            _, err = proc.communicate(timeout=HANG_S)
        except subprocess.TimeoutExpired:
            checked.hung = True
            checked.problems.append(f"hang: still running after {HANG_S:g} s")
            proc.kill()
            _, err = proc.communicate()
        finally:
            if helper is not None and helper.poll() is None:
                helper.kill()
                helper.communicate()
    checked.code = proc.returncode
    deadline = time.monotonic() + GONE_S
    while (left := marked(mark)) and time.monotonic() < deadline:
        time.sleep(0.1)
    if left:
        checked.orphans = len(left)
        checked.problems.append(f"orphans: {[(p.pid, p.name()) for p in left]}")
        for p in left:
            try:
                p.kill()
            except psutil.Error:
                pass
    if checked.code != EXPECTED[fault.kind]:
        checked.problems.append(f"exit code {checked.code}, documented "
                                f"{EXPECTED[fault.kind]}: {(err or '')[-600:]}")
    _check_records(fault, out, err or "", checked)
    checked.seconds = time.monotonic() - started
    return checked


def _inject(fault: Fault, proc: subprocess.Popen, env: dict) -> subprocess.Popen | None:
    """Strike (the faults that come from outside the run); a helper process, if any."""
    if fault.kind == "orchestrator_kill":
        time.sleep(fault.at)
        proc.kill()
        return None
    if fault.kind == "stray_publisher":
        time.sleep(fault.at)
        return subprocess.Popen([*SELF, "--publish", "/middle"], cwd=ROOT, env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    if fault.kind == "client_disconnect":
        client = subprocess.Popen([*SELF, "--step-client", "1000"], cwd=ROOT, env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        client.stdout.readline()  # 'stepping': the request (more steps than the run has)
        time.sleep(fault.at)      # is in flight; the run steps to its end without the client
        client.kill()  # gone mid-request, without a word
        client.communicate()
        return None
    return None


def _check_records(fault: Fault, out: Path, err: str, checked: Checked) -> None:
    """Every tick of every topic before the fault is readable; counts the missing ones."""
    runs = [p for p in out.iterdir() if p.is_dir()] if out.exists() else []
    if len(runs) != 1:
        if fault.kind != "orchestrator_kill":  # killed before it made its directory
            checked.problems.append(f"{len(runs)} run directories")
        return
    run_dir = runs[0]
    before = None  # ticks 0..before-1 must all be there
    if fault.kind in ("node_kill", "node_exit"):
        before = int(fault.at)
        if f"node tail died at tick {before}" not in err:
            checked.problems.append("the dying node's tick is not named")
    if fault.kind == "disk_full":
        manifest = _manifest(run_dir, checked)
        if manifest is None:
            return
        failure = manifest.get("write_failure") or {}
        before = failure.get("complete_ticks")
        if manifest["outputs"].get("bag") is None:
            finish = subprocess.run([*FINISH, str(run_dir)], cwd=ROOT, capture_output=True,
                                    text=True, timeout=HANG_S)
            if finish.returncode != 0:
                checked.problems.append(f"finish failed: {finish.stderr[-400:]}")
                return
        if before is None:
            checked.problems.append("the manifest does not say where the run stopped")
            return
    if fault.kind == "stray_publisher" and "Nothing was lost" not in err:
        checked.problems.append(f"the stray publisher was not named: {err[-1500:]}")
    ticks = _ticks_by_topic(run_dir, checked)
    for topic, period in PERIODS.items():
        have = ticks.get(topic, set())
        end = before if before is not None else (max(have) + 1 if have else 0)
        missing = [k for k in range(0, end, period) if k not in have]
        checked.lost += len(missing)
        if missing:
            checked.problems.append(f"{topic}: {len(missing)} tick(s) before the fault "
                                    f"missing, first {missing[0]}")


def _manifest(run_dir: Path, checked: Checked) -> dict | None:
    try:
        return json.loads((run_dir / "manifest.json").read_text())
    except (OSError, ValueError) as exc:
        checked.problems.append(f"manifest.json unreadable: {exc}")
        return None


def _ticks_by_topic(run_dir: Path, checked: Checked) -> dict[str, set[int]]:
    """The ticks each topic has in the bag (deserialised), or in the parts without one."""
    from runtime.recording import read_part

    tick_ns = 10_000_000  # long_chain: 100 Hz
    ticks: dict[str, set[int]] = {}
    if (run_dir / "bag").is_dir():
        from rosbags.highlevel import AnyReader

        try:
            with AnyReader([run_dir / "bag"]) as reader:
                for conn, stamp, raw in reader.messages():
                    reader.deserialize(raw, conn.msgtype)
                    ticks.setdefault(conn.topic, set()).add(stamp // tick_ns)
        except Exception as exc:  # noqa: BLE001 - an unreadable bag is what is checked
            checked.problems.append(f"bag unreadable: {exc}")
        return ticks
    for part in (run_dir / "parts").glob("*.rec"):
        for tick, topic, _ in read_part(part):
            ticks.setdefault(topic, set()).add(tick)
    return ticks


def series(faults: list[Fault], where: Path, say=print) -> list[Checked]:
    """Run every fault (one after the other); say one line per run."""
    results = []
    for i, fault in enumerate(faults):
        checked = run_one(fault, where / f"run{i:03d}")
        results.append(checked)
        verdict = "ok" if checked.ok else "; ".join(checked.problems)
        say(f"{i + 1:3d} {fault.describe():32s} exit {checked.code!s:4s} "
            f"{checked.seconds:5.1f} s  {verdict}")
    return results


def counts(results: list[Checked]) -> dict:
    """The series in numbers."""
    return {"runs": len(results),
            "faults_by_kind": dict(Counter(r.fault.kind for r in results)),
            "orphans": sum(r.orphans for r in results),
            "hangs": sum(r.hung for r in results),
            "records_lost": sum(r.lost for r in results),
            "wrong_exit_codes": sum(r.code != EXPECTED[r.fault.kind] for r in results),
            "runs_with_problems": sum(not r.ok for r in results),
            "seconds": round(sum(r.seconds for r in results), 1)}


# -- the helper programs: plain rclpy, as a user's would be -------------------------------

def _publish(topic: str) -> None:
    """A stray publisher: Int64 on ``topic`` at 50 Hz until killed."""
    import rclpy
    from std_msgs.msg import Int64

    rclpy.init()
    node = rclpy.create_node("stray_publisher")
    pub = node.create_publisher(Int64, topic, 10)
    while True:
        pub.publish(Int64(data=1086))
        time.sleep(0.02)


def _client(steps: int) -> None:
    """A client of the run's simulation services: ask for ``steps`` steps, say 'stepping'
    once the run moves, then wait for the answer (until killed)."""
    import rclpy
    from simulation_interfaces.srv import StepSimulation

    rclpy.init()
    node = rclpy.create_node("fault_client")
    client = node.create_client(StepSimulation, "/step_simulation")
    request = StepSimulation.Request(steps=steps)
    if not client.wait_for_service(timeout_sec=60):
        raise SystemExit("the run's services never appeared")
    end = time.monotonic() + 0.5  # discovery of the reply reader, both ways
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    clocks = []
    node.create_subscription(Clock, "/clock", clocks.append,
                             QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    future = client.call_async(request)
    while not clocks and not future.done():  # the run moves: the request arrived
        rclpy.spin_once(node, timeout_sec=0.05)
    print("stepping", flush=True)
    rclpy.spin_until_future_complete(node, future, timeout_sec=60)


def main(argv: list[str] | None = None) -> int:
    """Entry point: run a series and print its counts (or be one of the helper programs)."""
    p = argparse.ArgumentParser(prog="python -m bench.faults", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=len(KINDS) * 4)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--kinds", default=",".join(KINDS), help="comma-separated fault kinds")
    p.add_argument("--out", type=Path, help="keep the run directories here")
    p.add_argument("--publish", help=argparse.SUPPRESS)
    p.add_argument("--step-client", type=int, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.publish:
        _publish(args.publish)
        return 0
    if args.step_client is not None:
        _client(args.step_client)
        return 0
    kinds = tuple(k for k in args.kinds.split(",") if k)
    unknown = set(kinds) - set(KINDS)
    if unknown:
        p.error(f"unknown fault kind(s) {sorted(unknown)}; known: {', '.join(KINDS)}")
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    with tempfile.TemporaryDirectory(prefix="cosim-faults-") as scratch:
        where = args.out or Path(scratch)
        results = series(plan(args.seed, args.runs, kinds), where)
    print(json.dumps(counts(results), indent=2))
    return 0 if all(r.ok for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
