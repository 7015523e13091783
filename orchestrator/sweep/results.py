"""A sweep's results: one record per run on disk, and the table made from them.

Each finished run's record is written, the moment it arrives, to
``<sweep>/runs/<run id>/result.json`` (atomically), so a sweep that is stopped, killed or
interrupted keeps every finished run and ``--resume`` knows what to skip. The table
(``results.csv`` and ``results.parquet``) is written from the records at the end, one row
per run in the plan's order: run id, seed, the swept values (one column per key), status,
success, digest, wall time, run directory (relative to the sweep directory), error, where
it ran, then one column per metric.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from orchestrator.sweep.combinations import RunSpec

RECORD_NAME = "result.json"
TABLE_CSV, TABLE_PARQUET = "results.csv", "results.parquet"
FAILED = ("failed", "crashed", "timeout", "error")
"""Statuses of a run that did not finish normally (a node failed, the run's process died,
it hung, or something else broke)."""
FINISHED = ("success", "goal_not_met", *FAILED)
FIXED_COLUMNS = ("run_id", "seed")
OUTCOME_COLUMNS = ("status", "success", "digest", "wall_s", "run_dir", "error", "host",
                   "ros_domain")


class RunRecords:
    """The records of the runs of one sweep directory."""

    def __init__(self, sweep_dir: Path):
        self.sweep_dir = sweep_dir

    def path(self, run_id: str) -> Path:
        """Where a run's record lives."""
        return self.sweep_dir / "runs" / run_id / RECORD_NAME

    def save(self, record: dict[str, Any]) -> None:
        """Write a run's record (write to a temporary name, then rename: never half a file)."""
        path = self.path(record["run_id"])
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
        os.replace(tmp, path)

    def load(self) -> dict[str, dict[str, Any]]:
        """Every record found, by run id (unreadable ones are skipped: those runs rerun)."""
        found = {}
        for path in sorted((self.sweep_dir / "runs").glob(f"*/{RECORD_NAME}")):
            try:
                record = json.loads(path.read_text())
            except (OSError, ValueError):
                continue
            if record.get("status") in FINISHED:
                found[record["run_id"]] = record
        return found


def to_skip(specs: list[RunSpec], records: dict[str, dict[str, Any]],
            retry_failed: bool) -> set[str]:
    """The runs ``--resume`` skips: those with a record (failed ones too, unless
    ``retry_failed``)."""
    return {s.run_id for s in specs if s.run_id in records
            and not (retry_failed and records[s.run_id]["status"] in FAILED)}


def table_rows(specs: list[RunSpec], records: dict[str, dict[str, Any]],
               sweep_dir: Path) -> list[dict[str, Any]]:
    """One flat row per planned run that has a record, in the plan's order."""
    keys = list(specs[0].params) if specs else []
    metric_names = sorted({m for s in specs if s.run_id in records
                           for m in records[s.run_id].get("metrics", {})})
    rows = []
    for spec in specs:
        record = records.get(spec.run_id)
        if record is None:
            continue
        row: dict[str, Any] = {"run_id": spec.run_id, "seed": spec.seed}
        row.update({key: spec.params[key] for key in keys})
        row.update({col: record.get(col) for col in OUTCOME_COLUMNS})
        row["success"] = bool(record.get("success"))
        row["run_dir"] = _relative(record.get("run_dir"), sweep_dir)
        for name in metric_names:
            column = name if name not in row else f"metric.{name}"
            row[column] = record.get("metrics", {}).get(name)
        rows.append(row)
    return rows


def _relative(path: str | None, base: Path) -> str | None:
    """``path`` relative to ``base`` when it lies inside it (the table travels with the
    sweep directory), else as it is."""
    if not path:
        return None
    try:
        return str(Path(path).resolve().relative_to(base.resolve()))
    except ValueError:
        return path


def write_table(rows: list[dict[str, Any]], sweep_dir: Path) -> tuple[Path, Path]:
    """Write results.csv and results.parquet; return their paths."""
    import pyarrow as pa
    import pyarrow.csv as pa_csv
    import pyarrow.parquet as pq

    columns = list(rows[0]) if rows else [*FIXED_COLUMNS, *OUTCOME_COLUMNS]
    table = pa.table({name: _column([row.get(name) for row in rows]) for name in columns})
    csv_path, parquet_path = sweep_dir / TABLE_CSV, sweep_dir / TABLE_PARQUET
    pa_csv.write_csv(table, csv_path)
    pq.write_table(table, parquet_path)
    return csv_path, parquet_path


def _column(values: list[Any]):
    """An Arrow column: numbers, booleans and text as they are; anything else (a mixture,
    lists, mappings: a swept value can be any YAML) as its JSON text."""
    import pyarrow as pa

    present = [v for v in values if v is not None]
    kinds = {bool if isinstance(v, bool) else (float if isinstance(v, int | float) else type(v))
             for v in present}
    if not kinds:
        return pa.array(values, type=pa.string())
    if kinds == {bool}:
        return pa.array(values, type=pa.bool_())
    if kinds == {float}:
        ints = all(isinstance(v, int) for v in present)
        return pa.array(values, type=pa.int64() if ints else pa.float64())
    if kinds == {str}:
        return pa.array(values, type=pa.string())
    return pa.array([None if v is None else json.dumps(v, sort_keys=True) for v in values],
                    type=pa.string())
