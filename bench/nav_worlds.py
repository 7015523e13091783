"""The built-in controller, default parameters, over generated worlds: how often it gets there.

Each world (``bench.worldgen``: forests, corridors, mazes, rooms) is run in-process; a run
succeeds when the robot reached the goal without a collision (the scenario's success).
Prints one line per world, the success rate per family and overall, and each failure
with its report picture.

    python -m bench.nav_worlds [--count 50] [--first-seed 0] [--jobs 2] [--out DIR]
    python -m bench.nav_worlds --seeds 50 80      # just these worlds
"""

from __future__ import annotations

import time
from pathlib import Path

from bench import world_series

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
    seeds, jobs, out = world_series.parse(__doc__, 50, "cosim-nav-worlds-", argv)
    results, wall = world_series.run_all(
        run_world, seeds, out, jobs,
        lambda entry: (f"  {entry['name']:24s} way {entry['trip']:5.1f} m  {verdict(entry)}"
                       f"  ({entry['wall_s']:.1f} s)"))
    rate = world_series.tally(results, "success (goal reached, no collision)", TARGET, wall, jobs)
    for e in results:
        if not e["success"]:
            print(f"  failed: {e['name']} ({verdict(e)}): {e['report']}")
            for text in e["warnings"] + e["notes"]:
                print(f"    {text}")
    print(f"worlds and runs in {out}")
    return 0 if rate >= TARGET else 1


if __name__ == "__main__":
    raise SystemExit(main())
