"""Run directories: ``runs/<scenario>-<timestamp>/``, never reused, and the one object that
names every path inside one (the orchestrator writes them, node processes record into
them, the API, diff and report read them)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class RunPaths:
    """The paths of one run directory."""

    root: Path

    @property
    def manifest(self) -> Path:
        """manifest.json: what ran, the digest, the outcome and what it cost."""
        return self.root / "manifest.json"

    @property
    def bag(self) -> Path:
        """The rosbag2 (MCAP) directory."""
        return self.root / "bag"

    @property
    def report(self) -> Path:
        """report.png: the run in one picture."""
        return self.root / "report.png"

    @property
    def usd(self) -> Path:
        """run.usda: the run as an OpenUSD stage (--export-usd)."""
        return self.root / "run.usda"

    @property
    def checked_plan(self) -> Path:
        """The checked scenario the orchestrator hands to the node processes it execs."""
        return self.root / "plan.pickle"

    @property
    def logs(self) -> Path:
        """One log per node, and the orchestrator's."""
        return self.root / "logs"

    @property
    def parts(self) -> Path:
        """What each node recorded during the run (merged into the bag afterwards)."""
        return self.root / "parts"

    def log(self, node: str) -> Path:
        """A node's log (``orchestrator`` for the orchestrator's own)."""
        return self.logs / f"{node}.log"

    def part(self, node: str) -> Path:
        """What a node recorded: (tick, topic, bytes) records."""
        return self.parts / f"{node}.rec"

    def timing(self, node: str) -> Path:
        """A node's run-loop time split."""
        return self.logs / f"{node}.timing.json"

    def notes(self, node: str) -> Path:
        """What a node told people during the run (runtime.notes), one JSON a line."""
        return self.logs / f"{node}.notes.jsonl"

    def profile(self, node: str) -> Path:
        """A node's cProfile (run option ``profile``)."""
        return self.logs / f"{node}.prof"


def make_run_dir(root: Path, scenario_name: str) -> RunPaths:
    """Create a fresh run directory under ``root``; a suffix keeps same-second runs apart."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    root.mkdir(parents=True, exist_ok=True)
    for n in range(1000):
        path = root / (f"{scenario_name}-{stamp}" + (f"-{n}" if n else ""))
        try:
            path.mkdir()
            return RunPaths(path)
        except FileExistsError:
            continue
    raise RuntimeError(f"cannot create a run directory under {root}")


def out_problem(root: Path) -> str | None:
    """Why run directories cannot be made under ``root`` (a file where a directory must be,
    a directory not writable), or None. Checked before anything starts: bad input."""
    for path in (root, *root.parents):
        if not path.exists():
            continue
        if not path.is_dir():
            what = "is a file" if path == root else f"cannot be made: {path} is a file"
            return (f"--out {root} {what}; give a directory (made if missing) to receive "
                    "the run directory")
        if not os.access(path, os.W_OK | os.X_OK):
            return f"--out {root}: {path} is not writable; give a directory you can write to"
        return None
    return None
