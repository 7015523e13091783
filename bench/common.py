"""Helpers shared by the benchmarks: write a scenario, run it, read its manifest."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent


def bench_env(domain: int = 87) -> dict[str, str]:
    """An environment with its own ROS domain, so benchmarks never see other traffic."""
    env = dict(os.environ)
    env.setdefault("ROS_DOMAIN_ID", str(domain))
    return env


def write_scenario(doc: dict, directory: Path) -> Path:
    """Write a scenario dict as YAML and return its path."""
    path = directory / f"{doc['name']}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def run_manifest(scenario: Path, *args: str, out: Path | None = None,
                 env: dict[str, str] | None = None) -> dict:
    """Run cosim-orchestrate on a scenario (``env``: extra variables) and return its manifest."""
    out = out or Path(tempfile.mkdtemp(prefix="cosim-bench-"))
    cmd = [sys.executable, "-m", "orchestrator.cli", str(scenario), "--quiet", "--out", str(out),
           *args]
    proc = subprocess.run(cmd, env={**bench_env(), **(env or {})}, capture_output=True,
                          text=True, cwd=ROOT)
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
