"""Run directories: runs/<scenario>-<timestamp>/, never reused."""

from __future__ import annotations

import time
from pathlib import Path


def make_run_dir(root: Path, scenario_name: str) -> Path:
    """Create a fresh run directory under ``root``; a suffix keeps same-second runs apart."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    root.mkdir(parents=True, exist_ok=True)
    for n in range(1000):
        path = root / (f"{scenario_name}-{stamp}" + (f"-{n}" if n else ""))
        try:
            path.mkdir()
            return path
        except FileExistsError:
            continue
    raise RuntimeError(f"cannot create a run directory under {root}")
