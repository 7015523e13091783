"""The built-in controller, default parameters, over generated worlds: how often it gets there.

Each world (``bench.worldgen``: forests, corridors, mazes, rooms) is run in-process; a run
succeeds when the robot reached the goal without a collision (the scenario's success).
Prints one line per world, the success rate per family and overall, and each failure
with its report picture.

    python -m bench.nav_worlds [--count 50] [--first-seed 0] [--jobs 2] [--out DIR]
    python -m bench.nav_worlds --seeds 50 80      # just these worlds
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

TARGET = 0.95


def run_world(seed: int, out: Path) -> dict:
    """Generate world ``seed``, run it in-process, and say how it went."""
    import warnings

    from bench.worldgen import generate
    from orchestrator.api import ScenarioWarning, run

    world = generate(seed)
    scenario = world.write(out / "worlds")
    started = time.monotonic()
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        result = run(scenario, in_process=True, out=out / "runs", check=False)
    metrics = result.metrics
    return {"seed": seed, "name": world.name, "family": world.family, "trip": world.trip,
            "status": result.status, "success": result.success,
            "collisions": int(metrics.get("collisions", 0)),
            "time_to_goal": metrics.get("time_to_goal", -1.0),
            "recoveries": int(metrics.get("recoveries", 0)),
            "report": str(result.run_dir / "report.png"), "error": result.outcome.error,
            "notes": [n["text"] for n in result.manifest.get("notes", [])],
            "warnings": [str(w.message) for w in seen if issubclass(w.category, ScenarioWarning)],
            "wall_s": time.monotonic() - started}


def verdict(entry: dict) -> str:
    """'ok 23.4 s' or why it failed."""
    if entry["success"]:
        return f"ok {entry['time_to_goal']:.1f} s"
    if entry["status"] == "failed":
        return f"FAILED: {entry['error']}"
    why = []
    if entry["collisions"]:
        why.append(f"{entry['collisions']} collision(s)")
    if entry["time_to_goal"] < 0:
        why.append("goal not reached")
    return "MISSED: " + ", ".join(why or [entry["status"]])


def main(argv: list[str] | None = None) -> int:
    """Run the worlds; print the rate and the failures. Exit 0 when the rate meets TARGET."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--count", type=int, default=50, help="how many worlds (default 50)")
    p.add_argument("--first-seed", type=int, default=0, help="seed of the first world")
    p.add_argument("--seeds", type=int, nargs="+", help="these seeds instead of a range")
    p.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                   help="runs side by side, each in its own process (default 2)")
    p.add_argument("--out", type=Path, help="where worlds and runs go (default: a temp dir)")
    args = p.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix="cosim-nav-worlds-"))
    seeds = args.seeds or list(range(args.first_seed, args.first_seed + args.count))
    started = time.monotonic()
    results = []
    with ProcessPoolExecutor(args.jobs, mp_context=get_context("spawn")) as pool:
        for entry in pool.map(run_world, seeds, [out] * len(seeds)):
            results.append(entry)
            print(f"  {entry['name']:24s} way {entry['trip']:5.1f} m  {verdict(entry)}"
                  f"  ({entry['wall_s']:.1f} s)", flush=True)
    wall = time.monotonic() - started
    ok = sum(e["success"] for e in results)
    rate = ok / len(results)
    families = sorted({e["family"] for e in results})
    print("per family: " + ", ".join(
        f"{f} {sum(e['success'] for e in results if e['family'] == f)}/"
        f"{sum(e['family'] == f for e in results)}" for f in families))
    print(f"success (goal reached, no collision): {ok}/{len(results)} = {rate:.0%} "
          f"(target {TARGET:.0%}: {'met' if rate >= TARGET else 'NOT met'}); "
          f"{wall:.0f} s wall with {args.jobs} job(s), "
          f"{sum(e['wall_s'] for e in results):.0f} s of runs")
    for e in results:
        if not e["success"]:
            print(f"  failed: {e['name']} ({verdict(e)}): {e['report']}")
            for text in e["warnings"] + e["notes"]:
                print(f"    {text}")
    print(f"worlds and runs in {out}")
    return 0 if rate >= TARGET else 1


if __name__ == "__main__":
    raise SystemExit(main())
