"""Running the real command-line tools from tests."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ORCHESTRATE = [sys.executable, "-m", "orchestrator.cosim_orchestrate"]
"""The cosim-orchestrate command, run with this interpreter."""
COSIM_NODE = [sys.executable, "-m", "runtime.cosim_node"]
"""The cosim-node command, run with this interpreter."""
ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = Path(__file__).resolve().parent / "scenarios"
NAV = ROOT / "scenarios" / "nav.yaml"


def nav_without_camera_doc(duration: str) -> dict:
    """scenarios/nav.yaml as a document, its camera node left out, its world path absolute
    (so the document can be written anywhere), running ``duration``."""
    import yaml

    doc = yaml.safe_load(NAV.read_text())
    doc["duration"] = duration
    doc["world"] = str((NAV.parent / doc["world"]).resolve())
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] != "camera"]
    return doc


@dataclass
class CliRun:
    """A finished cosim-orchestrate process: exit code, output and its run directory."""

    code: int
    stdout: str
    stderr: str
    run_dir: Path | None

    @property
    def manifest(self) -> dict:
        """The run's manifest.json."""
        return json.loads((self.run_dir / "manifest.json").read_text())


def orchestrate(scenario: Path, out: Path, *args: str, timeout: float = 240,
                env: dict[str, str] | None = None, picture: bool = False) -> CliRun:
    """Run cosim-orchestrate as a real process (``env``: extra variables) and wait for it;
    without report.png unless ``picture`` (drawing it is most of a short run's CPU)."""
    import os

    before = set(out.glob("*")) if out.exists() else set()
    drawn = () if picture else ("--no-picture",)
    proc = subprocess.run([*ORCHESTRATE, str(scenario), "--out", str(out), *args, *drawn],
                          capture_output=True, text=True, timeout=timeout, cwd=ROOT,
                          env={**os.environ, **(env or {})})
    new = sorted(set(out.glob("*")) - before) if out.exists() else []
    return CliRun(proc.returncode, proc.stdout, proc.stderr, new[-1] if new else None)


def replayed_digest(run_dir: Path, out: Path) -> str:
    """``cosim-orchestrate --replay RUN_DIR --in-process`` from the run directory alone (the
    recorded requests fed back); the replay's digest, after checking it exits 0 and prints
    the digest its manifest has."""
    proc = subprocess.run([*ORCHESTRATE, "--replay", str(run_dir), "--in-process", "--quiet",
                           "--no-picture", "--out", str(out)], capture_output=True, text=True,
                          timeout=240, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    (replay_dir,) = out.iterdir()
    digest = json.loads((replay_dir / "manifest.json").read_text())["digest"]
    assert digest in proc.stdout, proc.stdout
    return digest


def node_process(orchestrator_pid: int, name: str):
    """The psutil process of node ``name`` among an orchestrator's children (by the process
    name every node gives itself, whether forked or started as a fresh interpreter)."""
    import psutil

    from runtime.parent import process_name

    for child in psutil.Process(orchestrator_pid).children():
        if child.name() == process_name(name):
            return child
    raise LookupError(name)
