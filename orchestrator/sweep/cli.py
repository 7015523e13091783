"""cosim-sweep: run a scenario over seeds and parameter values, each run isolated."""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from runtime.entry import guarded, interruptible

EXIT_ALL_SUCCEEDED, EXIT_GOAL_NOT_MET, EXIT_BAD_INPUT, EXIT_RUN_FAILED = 0, 1, 2, 3
EXIT_INTERRUPTED = 130
PICTURE_NAME = "summary.png"
DEFAULT_TIMEOUT_S = 3600.0

EPILOG = """\
isolation (runs side by side never hear each other, on a shared host too):
  in-process runs (the default) have no transport at all: nothing to isolate.
  --multi-process runs each hold a ROS domain id of their machine, leased with a lock
  ($TMPDIR/cosim-ros-domains/<id>.lock, about 100 ids per host) for the run's whole life;
  zenoh runs also have a session of their own (loopback, a free port, no multicast).

outputs in --out DIR:
  results.csv, results.parquet  one row per run: run_id, seed, the swept values, status,
                                success, digest, wall_s, run_dir, error, host, ros_domain,
                                then the metrics (time_to_goal, path_length, ...)
  summary.png                   success rate and metric distributions per swept value
  runs/<run id>/                each run: result.json, run.log and its run directory
  sweep.json                    the plan (scenario, seeds, values, backend)

a run's status: success, goal_not_met, failed (a node failed), crashed (the run's
process died), timeout (still going after --timeout: stopped), error (anything else).
A failed run is recorded with its error and never stops the sweep.

exit codes:
  0    every run succeeded
  1    every run finished, some missed the goal
  2    bad input (scenario, --seeds, --set, --ray address): nothing was started or written
  3    some runs failed, crashed or timed out (the others finished; see the table)
  70   internal error: an exception cosim did not expect (its fault, not a run's); the
       traceback is printed and kept in a file the last line names
  130  interrupted (Ctrl-C, SIGTERM): every run was stopped, no process is left, and the
       table holds the runs that finished; --resume goes on from there
"""


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    p = argparse.ArgumentParser(
        prog="cosim-sweep", epilog=EPILOG, formatter_class=argparse.RawTextHelpFormatter,
        description="Run a cosim scenario over every combination of seeds and parameter "
                    "values, each an isolated run,\non a local pool (default) or a Ray "
                    "cluster. Every run has the digest it has alone.")
    p.add_argument("scenario", type=Path, help="scenario YAML file, e.g. scenarios/nav.yaml")
    p.add_argument("--seeds", required=True,
                   help="seeds: a range, a list or both, e.g. 1-100, 1,5,9, 1-3,10")
    p.add_argument("--set", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="a scenario key and its values (YAML, comma-separated); repeat for\n"
                        "more keys: the sweep is the product. A single value just sets it.\n"
                        "e.g. --set nodes.control.params.max_speed=0.3,0.5")
    p.add_argument("--out", type=Path, required=True, metavar="DIR",
                   help="the sweep's directory")
    p.add_argument("--jobs", type=int, metavar="N",
                   help="runs at once (default: local, the cores / the processes of a run;\n"
                        "Ray, as many as the cluster's CPUs hold)")
    p.add_argument("--ray", metavar="ADDRESS",
                   help="run every run as a Ray task on the cluster at ADDRESS (host:port),\n"
                        "'auto' (the cluster this machine belongs to) or 'local' (a Ray\n"
                        "started for this sweep); a task asks for one CPU per process.\n"
                        "Needs pip install 'cosim[ray]'")
    p.add_argument("--multi-process", action="store_true",
                   help="every run with each node its own process, in lockstep over the\n"
                        "scenario's transport (default: in-process runs, the reference)")
    p.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S, metavar="S",
                   help=f"stop a run still going after S seconds and record it as timeout\n"
                        f"(default {DEFAULT_TIMEOUT_S:g})")
    p.add_argument("--resume", action="store_true",
                   help="go on with the sweep in --out: skip the runs that finished")
    p.add_argument("--retry-failed", action="store_true",
                   help="with --resume, run again the runs that failed, crashed or timed out")
    p.add_argument("--no-picture", action="store_true",
                   help="no report.png in each run's directory (about a CPU second a run;\n"
                        "the sweep's summary.png is drawn all the same)")
    p.add_argument("--quiet", action="store_true", help="print only the final summary")
    return p


@guarded("cosim-sweep")
def main(argv: list[str] | None = None) -> int:
    """Entry point of cosim-sweep."""
    if argv is None:  # a command (not a call from a program): its own ROS 2 libraries
        from runtime.ros_libraries import ensure_own_libraries

        ensure_own_libraries()
    args = build_parser().parse_args(argv)
    from orchestrator.sweep.checks import check_sweep
    from plan.errors import ScenarioError

    try:
        checked = check_sweep(args)
    except (ScenarioError, ValueError) as exc:
        print(f"cosim-sweep: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.ray and importlib.util.find_spec("ray") is None:
        print("cosim-sweep: error: --ray needs Ray, which is not installed: "
              "pip install 'cosim[ray]' (or 'ray[default]>=2.40,<3')", file=sys.stderr)
        return EXIT_BAD_INPUT
    backend = _backend(args, checked.specs[0].processes)
    try:
        if args.ray:
            backend.connect()
            backend.check_fits(checked.specs[0].processes)
    except (ConnectionError, ValueError, RuntimeError) as exc:
        print(f"cosim-sweep: error: --ray {args.ray}: {exc}", file=sys.stderr)
        _close(backend)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:  # before any run started
        _close(backend)
        print("cosim-sweep: interrupted before any run started", file=sys.stderr)
        return EXIT_INTERRUPTED
    try:
        return _sweep(args, checked, backend)
    finally:
        _close(backend)


def _backend(args: argparse.Namespace, processes: int):
    """The local pool or the Ray backend, as the options ask."""
    if args.ray:
        from orchestrator.sweep.ray_backend import RayPool

        return RayPool(args.ray, args.jobs, args.timeout)
    from orchestrator.sweep.local_pool import LocalPool

    jobs = args.jobs or max(1, len(os.sched_getaffinity(0)) // processes)
    return LocalPool(jobs, args.timeout, runs_per_worker=None if processes == 1 else 1)


def _close(backend) -> None:
    if hasattr(backend, "close"):
        backend.close()


def _sweep(args: argparse.Namespace, checked, backend) -> int:
    """Run what is left of the plan, then write the table and the picture."""
    from orchestrator.lockstep.supervisor import signals_ignored
    from orchestrator.sweep.checks import PLAN_NAME
    from orchestrator.sweep.progress import SweepProgress
    from orchestrator.sweep.results import RunRecords, to_skip

    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    (out / PLAN_NAME).write_text(json.dumps(checked.plan_doc, indent=1) + "\n")
    records = RunRecords(out)
    found = records.load() if args.resume else {}
    skip = to_skip(checked.specs, found, args.retry_failed)
    todo = [s for s in checked.specs if s.run_id not in skip]
    done = {rid: found[rid] for rid in skip}
    ran: list[str] = []
    progress = SweepProgress(len(todo), len(skip), args.quiet)

    def on_record(record: dict[str, Any]) -> None:
        records.save(record)
        done[record["run_id"]] = record
        ran.append(record["run_id"])
        progress.update(record)

    interruptible()  # SIGINT and SIGTERM: exit 130, even if started with them ignored
    started = time.monotonic()
    interrupted = False
    try:
        backend.run(todo, on_record, progress.poll)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        progress.close()
    with signals_ignored():
        return _report(args, checked, done, len(ran), time.monotonic() - started, interrupted)


def _report(args: argparse.Namespace, checked, done: dict[str, dict[str, Any]], ran: int,
            wall_s: float, interrupted: bool) -> int:
    """Write the table and picture; print the summary; the exit code."""
    from orchestrator.sweep.results import FAILED, table_rows, write_table
    from orchestrator.sweep.summary_picture import write_summary_png

    out: Path = args.out
    rows = table_rows(checked.specs, done, out)
    csv_path, parquet_path = write_table(rows, out)
    metrics = sorted({m for r in done.values() for m in r.get("metrics", {})})
    picture = None
    if rows:
        picture = write_summary_png(rows, list(checked.values), metrics, out / PICTURE_NAME,
                                    checked.name)
    statuses = [r["status"] for r in rows]
    ok = sum(1 for r in rows if r["success"])
    failed = [s for s in statuses if s in FAILED]
    kinds = ", ".join(f"{statuses.count(k)} {k}" for k in FAILED if k in failed)
    print(f"cosim-sweep: {len(rows)} of {len(checked.specs)} runs finished: {ok} succeeded, "
          f"{statuses.count('goal_not_met')} missed the goal, {len(failed)} failed"
          + (f" ({kinds})" if kinds else "")
          + (f"; success rate {100 * ok / len(rows):.0f} %" if rows else ""))
    print(f"  table:   {csv_path}, {parquet_path}")
    if picture:
        print(f"  picture: {picture}")
    skipped = len(rows) - ran
    print(f"  {ran} run(s) finished in {wall_s:.1f} s"
          + (f", {skipped} skipped as finished before (--resume)" if args.resume else ""))
    if interrupted:
        print("cosim-sweep: interrupted; every run was stopped. Go on with --resume.",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    if failed:
        return EXIT_RUN_FAILED
    return EXIT_GOAL_NOT_MET if "goal_not_met" in statuses else EXIT_ALL_SUCCEEDED



if __name__ == "__main__":
    sys.exit(main())
