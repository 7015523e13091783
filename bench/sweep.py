"""cosim-sweep's throughput: nav seeds in-process on every core, against runs alone.

In one invocation, side by side:

1. single runs alone: a few nav seeds spread over the sweep's range, one after the other,
   each an ordinary ``orchestrator.api.run(..., in_process=True)`` in a warm process (one
   warm-up run first), half of them before the sweeps and half after (the machine's speed
   drifts): the mean wall of one run;
2. the embedded pool: ``cosim-sweep scenarios/nav.yaml --seeds 1-N --jobs CORES`` as a
   command; efficiency = (N x single run wall / cores) / sweep wall (target >= 0.85);
3. the same sweep with ``--ray local`` (a Ray started for the sweep, CORES CPUs): Ray wall
   over embedded wall (target <= 1.2x);
4. what the machine itself allows: CORES processes each doing the single runs of 1. at
   the same time, no sweep involved: a run's wall alone over its wall side by side is the
   best any pool can reach here (1.0 on idle, independent cores; lower when other load
   or shared caches slow parallel runs down).

Sweep walls are the whole command (start-up, checks, table and picture included). Every
sweep run's digest is checked against the digest the same seed has alone, where both ran.

    python -m bench.sweep [--runs 100] [--singles 6] [--no-ray]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.common import ROOT, bench_env

NAV = ROOT / "scenarios" / "nav.yaml"
SWEEP = [sys.executable, "-m", "orchestrator.sweep"]


def single_runs(seeds: list[int], out: Path) -> dict[int, tuple[float, str, float]]:
    """Seed -> (wall s, digest, CPU s) of each run alone, in this process (after a warm-up
    run)."""
    from orchestrator.api import run

    run(NAV, in_process=True, out=out / "warm-up", seed=seeds[0] + 1000)
    found = {}
    for seed in seeds:
        cpu, started = _cpu_s(resource.RUSAGE_SELF), time.perf_counter()
        result = run(NAV, in_process=True, out=out / "alone", seed=seed)
        found[seed] = (time.perf_counter() - started, result.digest,
                       _cpu_s(resource.RUSAGE_SELF) - cpu)
    return found


def side_by_side(seeds: list[int], copies: int) -> float:
    """Mean wall of one run when ``copies`` processes each run ``seeds`` alone at once."""
    procs = [subprocess.Popen([sys.executable, "-m", "bench.sweep", "--alone",
                               ",".join(map(str, seeds))], cwd=ROOT, env=bench_env(),
                              stdout=subprocess.PIPE, text=True, start_new_session=True)
             for _ in range(copies)]  # each its own session, as commands from two shells
    walls = []
    for proc in procs:
        out, _ = proc.communicate(timeout=1800)
        walls += [wall for wall, _, _ in json.loads(out.splitlines()[-1]).values()]
    return statistics.mean(walls)


def _cpu_s(who: int) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def sweep(runs: int, jobs: int, out: Path, *extra: str) -> tuple[float, dict[int, dict], float]:
    """Run cosim-sweep as a command; its wall time, its table's rows by seed and the CPU
    time of its process tree (the workers of the embedded pool included; not Ray's)."""
    cpu, started = _cpu_s(resource.RUSAGE_CHILDREN), time.perf_counter()
    proc = subprocess.run([*SWEEP, str(NAV), "--seeds", f"1-{runs}", "--jobs", str(jobs),
                           "--out", str(out), "--quiet", *extra], cwd=ROOT, env=bench_env(),
                          capture_output=True, text=True, timeout=3600)
    wall = time.perf_counter() - started
    cpu = _cpu_s(resource.RUSAGE_CHILDREN) - cpu
    if proc.returncode not in (0, 1):
        raise RuntimeError(f"cosim-sweep exited {proc.returncode}:\n{proc.stderr[-2000:]}")
    with open(out / "results.csv", newline="") as f:
        rows = {int(r["seed"]): r for r in csv.DictReader(f)}
    return wall, rows, cpu


def check_digests(rows: dict[int, dict], alone: dict[int, tuple[float, str, float]],
                  label: str) -> str:
    """'equal' when every seed run alone has the same digest in the sweep."""
    wrong = [s for s, (_, digest, _) in alone.items()
             if s in rows and rows[s]["digest"] != digest]
    return "equal" if not wrong else f"DIFFERENT for seeds {wrong} ({label})"


def main(argv: list[str] | None = None) -> dict[str, float]:
    """Print the efficiency of the embedded pool and Ray's wall over it; return both."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--runs", type=int, default=100)
    p.add_argument("--singles", type=int, default=6, help="seeds run alone for the mean")
    p.add_argument("--no-ray", action="store_true", help="skip the Ray comparison")
    p.add_argument("--alone", help=argparse.SUPPRESS)  # side_by_side's processes
    args = p.parse_args(argv)
    if args.alone:
        with tempfile.TemporaryDirectory(prefix="cosim-bench-sweep-") as tmp:
            print(json.dumps(single_runs([int(s) for s in args.alone.split(",")], Path(tmp))))
        return {}
    cores = len(os.sched_getaffinity(0))
    picks = sorted({1 + i * (args.runs - 1) // max(args.singles - 1, 1)
                    for i in range(args.singles)})
    results: dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="cosim-bench-sweep-") as tmp:
        alone = single_runs(picks[::2], Path(tmp))
        wall, rows, cpu = sweep(args.runs, cores, Path(tmp) / "embedded")
        if not args.no_ray:
            ray_wall, ray_rows, _ = sweep(args.runs, cores, Path(tmp) / "ray", "--ray", "local")
        alone.update(single_runs(picks[1::2], Path(tmp)))
        paired = side_by_side(picks[::2], cores)
        single = statistics.mean(w for w, _, _ in alone.values())
        single_cpu = statistics.mean(c for _, _, c in alone.values())
        print(f"  nav in-process alone: {single:.2f} s per run, {single_cpu:.2f} s CPU (mean of "
              f"seeds {', '.join(map(str, alone))}: "
              f"{', '.join(f'{w:.2f}' for w, _, _ in alone.values())} s; half before the "
              "sweeps, half after)")
        ideal = args.runs * single / cores
        results["efficiency"] = ideal / wall
        ok = sum(1 for r in rows.values() if r["success"] == "true")
        print(f"  embedded pool, {args.runs} runs on {cores} cores: {wall:.1f} s (ideal "
              f"{ideal:.1f} s), {ok} succeeded, digests {check_digests(rows, alone, 'pool')} "
              "to runs alone")
        print(f"  CPU of the whole sweep (sweep process and workers): {cpu:.1f} s = "
              f"{cpu / (args.runs * single_cpu):.2f} x N x a run's CPU alone (the pool's own "
              "work; insensitive to other load)")
        print(f"  the machine: {cores} processes of single runs side by side, "
              f"{paired:.2f} s per run: at best {single / paired:.2f} for any pool here")
        print(f"sweep efficiency (N x single / cores / sweep wall): "
              f"{results['efficiency']:.2f} (target >= 0.85)")
        if not args.no_ray:
            results["ray_over_embedded"] = ray_wall / wall
            same = all(ray_rows[s]["digest"] == rows[s]["digest"] for s in rows)
            print(f"  Ray on this machine ({cores} CPUs): {ray_wall:.1f} s, digests "
                  f"{'equal to the embedded pool' if same else 'DIFFERENT'}, "
                  f"{check_digests(ray_rows, alone, 'ray')} to runs alone")
            print(f"Ray wall / embedded pool wall: {results['ray_over_embedded']:.2f}x "
                  f"(target <= 1.2x)")
    return results


if __name__ == "__main__":
    main()
