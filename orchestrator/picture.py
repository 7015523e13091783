"""report.png: a picture of the run for someone who never saw it."""

from __future__ import annotations

from pathlib import Path


def write_report_png(scenario, run_dir: Path, bag: Path | None) -> Path | None:
    """Draw the run from its bag into ``<run dir>/report.png``; None when there is nothing."""
    return None
