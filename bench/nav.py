"""The nav scenario: multi-process wall time over --in-process wall time, camera on and off;
real-time factor, start-up time and where the time goes, all from the runs' manifests.

    python -m bench.nav [--transport ros2] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
from pathlib import Path

import yaml

from bench.common import ROOT, run_manifest
from runtime.timing import PARTS

NAV = ROOT / "scenarios" / "nav.yaml"


def without_camera() -> Path:
    """nav.yaml minus its camera node, written beside it (its world path is relative)."""
    doc = yaml.safe_load(NAV.read_text())
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] != "camera"]
    path = NAV.with_name(f"_bench_nav_nocam_{os.getpid()}.yaml")
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def loop_s(manifest: dict) -> float:
    """Seconds of the tick loop (start-up and the work after the run excluded)."""
    return manifest["loop_s"]


def case(path: Path, transport: str) -> dict[str, dict]:
    """One multi-process and one in-process run of a scenario."""
    return {"multi": run_manifest(path, "--transport", transport),
            "inproc": run_manifest(path, "--in-process")}


def report(label: str, runs: dict[str, dict]) -> None:
    """Print one case: ratio of loops and of whole walls, RTF, digests equal."""
    multi, inproc = runs["multi"], runs["inproc"]
    same = "equal" if multi["digest"] == inproc["digest"] else "DIFFERENT"
    print(f"{label}: loop {loop_s(multi):.2f} s vs in-process {loop_s(inproc):.2f} s = "
          f"{loop_s(multi) / loop_s(inproc):.2f}x; whole run {multi['wall_time_s']:.2f} s vs "
          f"{inproc['wall_time_s']:.2f} s; RTF {multi['sim_time_s'] / loop_s(multi):.1f} vs "
          f"{inproc['sim_time_s'] / loop_s(inproc):.1f}; digests {same}")
    startup = multi.get("startup", {})
    print(f"  start-up: command to first tick {startup.get('command_to_first_tick_s', '-')} s, "
          f"run start to first tick {multi['start_s']:.2f} s; ready per node: " +
          ", ".join(f"{n} {v.get('ready_s', '-')} s" for n, v in multi["nodes"].items()))
    for name, node in multi["nodes"].items():
        split = node.get("time_s")
        if split:
            parts = ", ".join(f"{part} {split[part]:.2f}" for part in (*PARTS, "other"))
            print(f"  {name} run loop {split['run']:.2f} s: {parts}")
    print("  per node (multi-process): " + "; ".join(
        f"{n} step {v.get('step_ms_mean', 0):.2f} ms x {v.get('ticks', 0)}, CPU "
        f"{v.get('cpu_s', '-')} s" for n, v in multi["nodes"].items()))


def main(argv: list[str] | None = None) -> None:
    """Run nav with and without the camera, ``--repeats`` times interleaved; then the
    median ratio of each case (this machine's speed drifts between minutes)."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--transport", default="ros2")
    p.add_argument("--repeats", type=int, default=1)
    args = p.parse_args(argv)
    nocam = without_camera()
    ratios: dict[str, list[float]] = {"camera on": [], "camera off": []}
    try:
        for repeat in range(args.repeats):
            for label, path in (("camera on", NAV), ("camera off", nocam)):
                runs = case(path, args.transport)
                report(f"nav, {label:10s}", runs)
                ratios[label].append(loop_s(runs["multi"]) / loop_s(runs["inproc"]))
            if repeat == 0:
                fresh = run_manifest(NAV, "--transport", args.transport, "--spawn", "exec")
                print(f"  start-up with fresh interpreters (--spawn exec) instead of "
                      f"forks: command to first tick "
                      f"{fresh.get('startup', {}).get('command_to_first_tick_s', '-')} s, "
                      f"run start to first tick {fresh['start_s']:.2f} s")
    finally:
        nocam.unlink()
    if args.repeats > 1:
        print(f"median multi / in-process loop over {args.repeats} repeats ({args.transport}): "
              + ", ".join(f"{label} {statistics.median(r):.2f}x (range {min(r):.2f}-"
                          f"{max(r):.2f}x)" for label, r in ratios.items()))


if __name__ == "__main__":
    main()
