"""A robot entering a running swarm: what the tick it enters costs, and whether the ticks
after it run as fast as in a run that had the robot from the start (issue 49's benchmark).

    python -m bench.spawn [--robots 16] [--seconds 4] [--enter 2s] [--pack kind] [--repeats 1]

bench.swarm's scenario of N robots (a lidar and the built-in controller each, physics at
50 Hz), multi-process. Two runs, side by side in one invocation:

- ``enters``: N robots from the start, and one more robot (``late``, with the same two
  nodes from the scenario's ``for_each: robot`` templates) entering at ``--enter``;
- ``from the start``: the same N robots and ``late`` entering at the first tick (20 ms), so
  the same N + 1 robots run every tick after ``--enter``.

Each tick's wall time is when the orchestrator decides it (``execute``'s ``on_tick``).
Ticks are decided in bursts (the lidars and controllers act every fifth physics tick), so
time is counted per window of the slowest node's period (100 ms simulated): a window's cost
is the wall between the decisions of its last tick and the last tick of the window before.
Reported: the cost of the window the robot enters in and of the next one, over the median
window of the same run before it (their excess: what entering costs); the median window
after entering against the median window of the run that had the robot from the start
(their ratio: 1.0 is "as fast"). Figures mean something only on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import yaml

from bench.swarm import scenario as swarm_scenario

WINDOW_NS = 100_000_000  # the slowest node's period: ticks are decided in bursts of it


def with_entering(path: Path, at: str) -> Path:
    """The swarm scenario with robot ``late`` entering at ``at``, written beside it."""
    doc = yaml.safe_load(path.read_text())
    doc["events"] = [{"at": at, "robot": {"name": "late", "start": {"x": 0.0, "y": 0.0,
                                                                    "yaw": 0.0},
                                          "goal": {"x": 0.5, "y": 0.0}}}]
    doc["name"] = f"{doc['name']}_late_{at}"
    out = path.with_name(f"{doc['name']}.yaml")
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


def window_walls(path: Path, pack: str, out: Path) -> tuple[list[float], int]:
    """The wall time of each window of WINDOW_NS simulated (from the decision of the window
    before's last tick to its own last), and the ticks per window."""
    import nodes  # noqa: F401 - the node kinds, for the plan
    from descriptions.load import load_scenario
    from orchestrator.execute import execute
    from plan.options import RunOptions

    scenario = load_scenario(path)
    per = WINDOW_NS // scenario.tick_ns
    stamps: dict[int, float] = {}
    options = RunOptions().with_(out=out, in_process=False, pack=pack)
    outcome = execute(scenario, options,
                      on_tick=lambda tick: stamps.__setitem__(tick, time.monotonic()))
    if outcome.status not in ("success", "goal_not_met") or outcome.result is None:
        raise RuntimeError(f"{path.name}: {outcome.status}: {outcome.error}")
    ends = [stamps[t] for t in sorted(stamps) if (t + 1) % per == 0]
    return [b - a for a, b in zip(ends, ends[1:], strict=False)], per


def measure(robots: int, seconds: float, enter: str, pack: str, directory: Path) -> dict:
    """One pair of runs: the robot entering mid-run and from the start."""
    from plan.timeutil import parse_duration_ns

    base = swarm_scenario(robots, seconds, directory)
    late = with_entering(base, enter)
    early = with_entering(base, "20ms")  # the first tick after the start (physics: 50 Hz)
    walls, _ = window_walls(late, pack, directory / "runs")
    ref, _ = window_walls(early, pack, directory / "runs")
    # walls[i] is window i+1's; the robot enters in window w
    w = parse_duration_ns(enter) // WINDOW_NS
    before = statistics.median(walls[1: w - 1])  # the first window holds the start-up
    after = statistics.median(walls[w + 1:])
    ref_after = statistics.median(ref[w + 1:])
    return {"robots": robots, "pack": pack, "enter_window": w,
            "median_window_s": before, "entering_windows_s": walls[w - 1: w + 1],
            "entering_extra_s": sum(x - before for x in walls[w - 1: w + 1]),
            "after_median_s": after, "from_start_median_s": ref_after,
            "after_over_from_start": after / ref_after}


def main(argv: list[str] | None = None) -> list[dict]:
    """Measure and print each repeat."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--enter", default="2s")
    parser.add_argument("--pack", default="kind", help="--pack of the runs (node, kind, robot)")
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args(argv)
    rows = []
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory(prefix="cosim-bench-spawn-") as tmp:
            row = measure(args.robots, args.seconds, args.enter, args.pack, Path(tmp))
        rows.append(row)
        print(f"{row['robots']} robots + 1 entering in 100 ms window {row['enter_window']} "
              f"(--pack {row['pack']}): median window before it "
              f"{row['median_window_s'] * 1e3:.1f} ms; the entering window and the next "
              f"{', '.join(f'{x * 1e3:.1f}' for x in row['entering_windows_s'])} ms, extra "
              f"over the median {row['entering_extra_s']:.3f} s; after it "
              f"{row['after_median_s'] * 1e3:.1f} ms a window vs "
              f"{row['from_start_median_s'] * 1e3:.1f} ms with the robot from the start "
              f"({row['after_over_from_start']:.2f}x)", flush=True)
    return rows


if __name__ == "__main__":
    main()
