"""nav with the Foxglove live view (--live) and one client subscribed to every topic, against
nav without it; both multi-process, run interleaved in one invocation. The client is
Foxglove's own (@foxglove/ws-protocol under node, tests/js), decoding every message.
Target (issue 21): at most 10% more wall time, the same digest.

    .venv/bin/python -m bench.live [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import shutil
import socket
import statistics
import subprocess
import tempfile
from pathlib import Path

import yaml

from bench.common import ROOT, bench_env, run_manifest, write_scenario

NAV = ROOT / "scenarios" / "nav.yaml"
CLIENT = ROOT / "tests" / "js" / "foxglove_client.mjs"


def nav(tmp: Path) -> tuple[Path, list[str]]:
    """nav.yaml as it is (world made absolute), and its topics."""
    import nodes  # noqa: F401 - provides the node kinds to the plan (plan.kinds)
    from descriptions.load import load_scenario

    doc = yaml.safe_load(NAV.read_text())
    doc["world"] = str((NAV.parent / doc["world"]).resolve())
    path = write_scenario(doc, tmp)
    return path, ["/clock", *sorted(load_scenario(path).topics)]


def free_port() -> int:
    """A loopback port free now."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def with_client(scenario: Path, topics: list[str]) -> tuple[dict, dict]:
    """One run with --live and the client subscribed to ``topics``: (manifest, what the
    client received). The client starts first and connects as soon as the server listens."""
    port = free_port()
    client = subprocess.Popen(["node", str(CLIENT), f"ws://127.0.0.1:{port}", "--topics",
                               ",".join(topics), "--drive", "no", "--seconds", "600"],
                              cwd=CLIENT.parent, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, env=bench_env())
    try:
        manifest = run_manifest(scenario, "--live", f"127.0.0.1:{port}")
        out, _ = client.communicate(timeout=60)
    finally:
        if client.poll() is None:
            client.kill()
            client.communicate()
    lines = out.strip().splitlines()
    return manifest, (json.loads(lines[-1]) if lines else {})


def main(argv: list[str] | None = None) -> float:
    """Print wall times and the ratio; return the median ratio."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)
    if not shutil.which("node") or not (CLIENT.parent / "node_modules").is_dir():
        print("bench.live: needs node and tests/js/node_modules (make install); skipped")
        return float("nan")
    ratios, loops = [], []
    with tempfile.TemporaryDirectory(prefix="cosim-bench-") as tmp:
        scenario, topics = nav(Path(tmp))
        for _ in range(args.repeats):
            plain = run_manifest(scenario)
            live, got = with_client(scenario, topics)
            ratio = live["wall_time_s"] / plain["wall_time_s"]
            ratios.append(ratio)
            loops.append(live["loop_s"] / plain["loop_s"])
            same = "equal" if live["digest"] == plain["digest"] else "DIFFERENT"
            received = sum(t["count"] for t in got.get("topics", {}).values())
            print(f"  nav {plain['wall_time_s']:6.2f} s wall (loop {plain['loop_s']:.2f} s, "
                  f"{plain['ticks']} ticks), with --live and a client on {len(topics)} topics "
                  f"{live['wall_time_s']:6.2f} s (loop {live['loop_s']:.2f} s; the client "
                  f"decoded {received} messages in {got.get('cpu_s', 0):.2f} s CPU; "
                  f"orchestrator CPU "
                  f"{plain['orchestrator']['cpu_s']:.2f} -> {live['orchestrator']['cpu_s']:.2f}"
                  f" s): {ratio:.2f}x, digests {same}")
    median = statistics.median(ratios)
    print(f"nav with --live and one client / without, wall, median of {args.repeats}: "
          f"{median:.2f}x (target <= 1.10x); tick loop alone {statistics.median(loops):.2f}x")
    return median


if __name__ == "__main__":
    main()
