"""Helpers shared by the benchmarks: write a scenario, run it, read its manifest."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

ORCHESTRATE = [sys.executable, "-m", "orchestrator.cosim_orchestrate"]
"""cosim-orchestrate, run with this interpreter."""

ROOT = Path(__file__).resolve().parent.parent
RUN_TIMEOUT_S = 300  # no benchmark run may hang the whole `make bench`


BENCH_DOMAIN = "87"
# The benchmark processes themselves talk ROS too (the message round trips): they and every
# process they start share one domain of their own, whatever the shell says.
os.environ.setdefault("ROS_DOMAIN_ID", BENCH_DOMAIN)


def bench_env() -> dict[str, str]:
    """The environment of benchmark subprocesses: this process's, with its ROS domain."""
    return dict(os.environ)


def write_scenario(doc: dict, directory: Path) -> Path:
    """Write a scenario dict as YAML and return its path."""
    path = directory / f"{doc['name']}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def run_manifest(scenario: Path, *args: str, out: Path | None = None,
                 env: dict[str, str] | None = None) -> dict:
    """Run cosim-orchestrate on a scenario (``env``: extra variables) and return its manifest."""
    out = out or Path(tempfile.mkdtemp(prefix="cosim-bench-"))
    cmd = [*ORCHESTRATE, str(scenario), "--quiet", "--out", str(out),
           *args]
    proc = subprocess.run(cmd, env={**bench_env(), **(env or {})}, capture_output=True,
                          text=True, cwd=ROOT, timeout=RUN_TIMEOUT_S)
    runs = sorted(out.glob("*/manifest.json"), key=lambda p: p.stat().st_mtime)
    if not runs:
        raise RuntimeError(f"{' '.join(cmd)} wrote no manifest:\n{proc.stderr}")
    return json.loads(runs[-1].read_text())


def counter(name: str, rate: int, inputs: list[str] = ()) -> dict:
    """A counter node spec publishing /<name>."""
    return {"name": name, "kind": "counter", "rate": rate, "params": {"output": f"/{name}"},
            "inputs": [{"topic": t, "mode": "same_tick"} for t in inputs]}


def cpu_s(manifest: dict) -> float:
    """CPU seconds of every process of a multi-process run (orchestrator and nodes)."""
    return manifest["orchestrator"]["cpu_s"] + sum(
        n.get("cpu_s", 0.0) for n in manifest["nodes"].values())
