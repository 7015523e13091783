"""A series of generated worlds, one run each, side by side in processes: the command line,
the loop and the tally that bench.nav_worlds and bench.crowd_worlds share."""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path


def parse(description: str, count: int, prefix: str, argv: list[str] | None
          ) -> tuple[list[int], int, Path]:
    """The seeds, the jobs and the output folder a series command was given (``count``
    worlds by default; a temp dir named ``prefix`` when no --out)."""
    p = argparse.ArgumentParser(description=description,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--count", type=int, default=count, help=f"how many worlds (default {count})")
    p.add_argument("--first-seed", type=int, default=0, help="seed of the first world")
    p.add_argument("--seeds", type=int, nargs="+", help="these seeds instead of a range")
    p.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                   help="runs side by side, each in its own process (default 2)")
    p.add_argument("--out", type=Path, help="where worlds and runs go (default: a temp dir)")
    args = p.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix=prefix))
    seeds = args.seeds or list(range(args.first_seed, args.first_seed + args.count))
    return seeds, args.jobs, out


def run_all(run_world: Callable[[int, Path], dict], seeds: list[int], out: Path, jobs: int,
            line: Callable[[dict], str]) -> tuple[list[dict], float]:
    """Each seed's world run by ``run_world`` in a pool of ``jobs`` spawned processes, a
    ``line`` printed for each as it ends; the results in seed order and the wall time."""
    started = time.monotonic()
    results = []
    with ProcessPoolExecutor(jobs, mp_context=get_context("spawn")) as pool:
        for entry in pool.map(run_world, seeds, [out] * len(seeds)):
            results.append(entry)
            print(line(entry), flush=True)
    return results, time.monotonic() - started


def tally(results: list[dict], what: str, target: float, wall: float, jobs: int) -> float:
    """Print the successes per family and in all against ``target`` (``what``: what success
    means); the success rate."""
    ok = sum(e["success"] for e in results)
    rate = ok / len(results)
    families = sorted({e["family"] for e in results})
    print("per family: " + ", ".join(
        f"{f} {sum(e['success'] for e in results if e['family'] == f)}/"
        f"{sum(e['family'] == f for e in results)}" for f in families))
    print(f"{what}: {ok}/{len(results)} = {rate:.0%} "
          f"(target {target:.0%}: {'met' if rate >= target else 'NOT met'}); "
          f"{wall:.0f} s wall with {jobs} job(s), "
          f"{sum(e['wall_s'] for e in results):.0f} s of runs")
    return rate
