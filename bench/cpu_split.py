"""CPU seconds per process (from the run manifests) for the two overhead comparisons of
issue 31 item 3: nav's built-in controller against the same controller as a foreign rclpy
program, and nav without against with ``--live`` and one Foxglove client. CPU seconds, not
wall, so the figures mean something on a loaded machine (wall ratios: bench.foreign_nav and
bench.live on an idle one).

    python -m bench.cpu_split [--repeats 1] [--case foreign|live|both]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from bench import foreign_nav, live
from bench.common import run_manifest


def split(manifest: dict) -> dict[str, float]:
    """CPU seconds by process: the orchestrator and each node."""
    out = {"orchestrator": manifest["orchestrator"]["cpu_s"]}
    out.update({name: n.get("cpu_s", 0.0) for name, n in manifest["nodes"].items()})
    return out


def show(label: str, a: dict, b: dict) -> None:
    """One comparison: per-process CPU, the total, the digests and the ticks."""
    ca, cb = split(a), split(b)
    print(f"{label}: ticks {a['ticks']} / {b['ticks']}, digest {a['digest'][:12]} / "
          f"{b['digest'][:12]}")
    for name in sorted(set(ca) | set(cb)):
        print(f"  {name:14s} {ca.get(name, 0.0):7.2f} -> {cb.get(name, 0.0):7.2f} s CPU")
    print("  wall (meaningful on an idle machine only): " + ", ".join(
        f"{key} {a[key]:.2f} -> {b[key]:.2f} s" for key in ("start_s", "loop_s", "wall_time_s")))
    ta, tb = sum(ca.values()), sum(cb.values())
    print(f"  {'total':14s} {ta:7.2f} -> {tb:7.2f} s CPU ({tb / ta:.2f}x)")


def main(argv: list[str] | None = None) -> None:
    """Run each case ``--repeats`` times and print CPU seconds per process."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeats", type=int, default=1)
    p.add_argument("--case", choices=["foreign", "live", "both"], default="both")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="cosim-bench-") as tmp:
        for _ in range(args.repeats):
            if args.case in ("foreign", "both"):
                builtin, foreign = foreign_nav.scenarios(Path(tmp))
                show("nav built-in -> foreign rclpy control", run_manifest(builtin),
                     run_manifest(foreign))
            if args.case in ("live", "both"):
                scenario, topics = live.nav(Path(tmp))
                plain = run_manifest(scenario)
                with_live, got = live.with_client(scenario, topics)
                show("nav -> nav --live with one client", plain, with_live)
                received = sum(t["count"] for t in got.get("topics", {}).values())
                print(f"  (client decoded {received} messages, {got.get('cpu_s', 0):.2f} s CPU)")


if __name__ == "__main__":
    main()
