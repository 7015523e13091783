"""Lockstep cost: ticks/s of trivial node processes, beside a bare rclpy ping-pong floor.

    python -m bench.lockstep [--seconds 3]

Prints ticks/s for a same-tick chain of 3 nodes and for 1, 3 and 6 independent nodes,
each over the full protocol (clock, status reports, sequence checks, digest), and the
round trips/s of two bare rclpy processes exchanging one message each way (the floor).
The chain also runs strictly in lockstep (--no-pipeline: every node finishes tick k
before /clock says k + 1) beside the default pipelined protocol, with the CPU time all
processes spent per tick (less sensitive to other load on the machine than ticks/s).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench.common import bench_env, counter, cpu_s, run_manifest, write_scenario

RATE = 1000


def chain(n: int, seconds: int) -> dict:
    """A same-tick chain n0 -> n1 -> ... of n counters."""
    nodes = [counter("n0", RATE)]
    nodes += [counter(f"n{i}", RATE, [f"/n{i - 1}"]) for i in range(1, n)]
    return {"name": f"chain{n}", "duration": f"{seconds}s", "nodes": nodes,
            "deadlines": {"start": "60s"}}


def parallel(n: int, seconds: int) -> dict:
    """n independent counters, all due every tick."""
    return {"name": f"parallel{n}", "duration": f"{seconds}s",
            "nodes": [counter(f"p{i}", RATE) for i in range(n)], "deadlines": {"start": "60s"}}


def ping_pong(round_trips: int = 3000) -> float:
    """Round trips/s between two bare rclpy processes (wait set + take, no executor)."""
    child = subprocess.Popen([sys.executable, "-m", "bench.pingpong", "pong", str(round_trips)],
                             env=bench_env())
    try:
        out = subprocess.run([sys.executable, "-m", "bench.pingpong", "ping", str(round_trips)],
                             env=bench_env(), capture_output=True, text=True, check=True,
                             timeout=120)
        return float(out.stdout.split()[-1])
    finally:
        try:
            child.wait(timeout=30)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()


def chain_modes(seconds: int, transport: str, tmp: Path,
                repeats: int = 1) -> list[tuple[str, float]]:
    """The 3-node chain pipelined and strictly in lockstep, ``repeats`` times interleaved,
    with CPU us per tick (the CPU of a 1-tick run, i.e. start-up and the work after the
    run, subtracted); rows give the median ticks/s of each mode."""
    doc = chain(3, seconds)
    base_doc = {**doc, "name": "chain3_base", "duration": "1ms"}
    rates: dict[str, list[float]] = {"pipelined": [], "strict lockstep": []}
    for _ in range(repeats):
        for label, flags in (("pipelined", []), ("strict lockstep", ["--no-pipeline"])):
            base = run_manifest(write_scenario(base_doc, tmp), "--transport", transport, *flags)
            m = run_manifest(write_scenario(doc, tmp), "--transport", transport, *flags)
            per_tick = (cpu_s(m) - cpu_s(base)) / m["ticks"] * 1e6
            print(f"  chain3 {label:16s} {m['ticks_per_s']:8.0f} ticks/s  {per_tick:6.0f} us "
                  f"CPU per tick (all processes)  digest {m['digest'][:12]}")
            rates[label].append(m["ticks_per_s"])
    return [(f"chain3 {label} over {transport} (ticks/s, median of {len(r)})",
             statistics.median(r)) for label, r in rates.items()]


def main(argv: list[str] | None = None) -> list[tuple[str, float]]:
    """Run every case and print a table; returns (case, ticks/s) rows."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--seconds", type=int, default=3, help="sim seconds per case at 1 kHz")
    p.add_argument("--transport", default="ros2")
    p.add_argument("--chain-repeats", type=int, default=1,
                   help="runs of the chain in each mode (the median is reported)")
    p.add_argument("--parallel", type=int, nargs="*", default=[1, 3, 6],
                   help="numbers of independent nodes to measure (scaling: 1 2 3 4 5 6 7 8)")
    args = p.parse_args(argv)
    rows = [("bare rclpy ping-pong (round trips/s)", ping_pong())]
    with tempfile.TemporaryDirectory() as tmp:
        rows += chain_modes(args.seconds, args.transport, Path(tmp), args.chain_repeats)
        cases = [chain(3, args.seconds)] + [parallel(n, args.seconds) for n in args.parallel]
        for doc in cases:
            m = run_manifest(write_scenario(doc, Path(tmp)), "--transport", args.transport)
            rows.append((f"{doc['name']} over {args.transport} (ticks/s)", m["ticks_per_s"]))
            inproc = run_manifest(write_scenario(doc, Path(tmp)), "--in-process")
            rows.append((f"{doc['name']} in-process (ticks/s)", inproc["ticks_per_s"]))
    floor = rows[0][1]
    for name, value in rows:
        print(f"{name:48s} {value:10.0f}   {value / floor:6.2f} x ping-pong")
    return rows


if __name__ == "__main__":
    main()
