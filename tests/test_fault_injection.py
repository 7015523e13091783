"""The fault-injection series, short (bench/faults.py runs the long one): one run per fault
kind, seeded: a node killed and one exiting at a random tick, the orchestrator SIGKILLed at
a random moment, the disk filling, a stray publisher, a client gone mid-request. Each run:
no process left, no hang, the exit code documented for its fault, every tick before the
fault readable (issue 40)."""

from __future__ import annotations

from bench.faults import KINDS, counts, plan, series


def test_a_seeded_series_of_faults_leaves_nothing_wrong(tmp_path):
    lines: list[str] = []
    results = series(plan(seed=40, runs=len(KINDS)), tmp_path, say=lines.append)
    summary = counts(results)
    assert summary["faults_by_kind"] == dict.fromkeys(KINDS, 1)
    assert summary["orphans"] == summary["hangs"] == summary["records_lost"] == 0, lines
    assert summary["wrong_exit_codes"] == 0 and summary["runs_with_problems"] == 0, lines
