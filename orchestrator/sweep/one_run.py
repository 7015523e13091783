"""One run of a sweep, wherever it runs (a local worker process or a Ray task).

A run is ``orchestrator.api.run`` with the run's seed and values, exactly as the same run
alone (``cosim-orchestrate SCENARIO --seed S --set KEY=V``), so it has the same digest.
Isolation from the runs beside it: an in-process run has no transport at all; a
multi-process run holds a leased ROS domain id of this machine for its whole life
(``orchestrator.domains``), and a zenoh run also has its own session (loopback, a free
port, no multicast scouting). The run's own output (warnings, a crash's traceback) goes to
``run.log`` in its directory.
"""

from __future__ import annotations

import faulthandler
import os
import shutil
import socket
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from orchestrator.sweep.combinations import RunSpec

LOG_NAME = "run.log"
DOMAIN_WAIT_S = 600.0  # a multi-process run waits this long for a ROS domain id to come free


def base_record(spec: RunSpec) -> dict[str, Any]:
    """A run's record before it has an outcome: who it is and where it writes."""
    return {"run_id": spec.run_id, "seed": spec.seed, "params": dict(spec.params),
            "status": None, "success": False, "digest": None, "wall_s": None,
            "run_dir": None, "error": None, "metrics": {}, "ros_domain": None,
            "host": socket.gethostname()}


def prepare(spec: RunSpec) -> None:
    """A fresh directory for the run (what an unfinished earlier attempt left is removed)."""
    if spec.out.exists():
        shutil.rmtree(spec.out)
    spec.out.mkdir(parents=True)


def run_logged(spec: RunSpec | dict[str, Any]) -> dict[str, Any]:
    """Prepare the run's directory and run it with its output in run.log; its record.

    KeyboardInterrupt (Ctrl-C, a stop, a timeout's SIGTERM) propagates after the run's own
    clean-up: an interrupted run has no record.
    """
    spec = spec if isinstance(spec, RunSpec) else RunSpec.from_dict(spec)
    prepare(spec)
    with output_to(spec.out / LOG_NAME):
        return execute_run(spec)


def execute_run(spec: RunSpec) -> dict[str, Any]:
    """Run ``spec`` and return its record (status, success, digest, metrics, wall time)."""
    from orchestrator.api import run
    from orchestrator.domains import DomainLease
    from plan.options import RunOptions

    record = base_record(spec)
    started = time.monotonic()
    options = RunOptions(picture=spec.picture)
    try:
        if spec.in_process:
            result = run(spec.scenario, in_process=True, out=spec.out, check=False,
                         overrides=spec.overrides(), options=options)
        else:
            with DomainLease(wait_s=DOMAIN_WAIT_S) as domain, ros_domain(domain):
                record["ros_domain"] = domain
                result = run(spec.scenario, in_process=False, out=spec.out, check=False,
                             overrides=spec.overrides(), options=options)
    except Exception as exc:  # noqa: BLE001 - any failure of one run is that run's outcome
        record.update(status="error", error=f"{type(exc).__name__}: {exc}",
                      run_dir=str(find_run_dir(spec)) if find_run_dir(spec) else None)
    else:
        record.update(status=result.status, success=result.success, digest=result.digest,
                      run_dir=str(result.run_dir), error=result.error,
                      metrics=flat_metrics(result.metrics_by_node))
    record["wall_s"] = time.monotonic() - started
    return record


def flat_metrics(by_node: dict[str, dict[str, Any]]) -> dict[str, float]:
    """One mapping of every node's numeric metrics: a name only one node reports as it is
    ('time_to_goal'), a name several report as '<node>.<name>' for each."""
    owners: dict[str, int] = {}
    for metrics in by_node.values():
        for name in metrics:
            owners[name] = owners.get(name, 0) + 1
    return {(name if owners[name] == 1 else f"{node}.{name}"): float(value)
            for node, metrics in sorted(by_node.items()) for name, value in metrics.items()
            if isinstance(value, int | float)}


def find_run_dir(spec: RunSpec) -> Path | None:
    """The run directory made inside the run's own directory, if one was made."""
    found = sorted(p for p in spec.out.glob("*") if p.is_dir()) if spec.out.exists() else []
    return found[-1] if found else None


def last_log_line(spec: RunSpec) -> str | None:
    """The last non-empty line the run wrote to run.log (a crash's last words), if any."""
    try:
        lines = (spec.out / LOG_NAME).read_text(errors="replace").splitlines()
    except OSError:
        return None
    lines = [line.strip() for line in lines if line.strip()]
    return lines[-1][:300] if lines else None


@contextmanager
def ros_domain(domain: int) -> Iterator[None]:
    """ROS_DOMAIN_ID = domain for this process and what it starts, restored afterwards."""
    saved = os.environ.get("ROS_DOMAIN_ID")
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    try:
        yield
    finally:
        if saved is None:
            os.environ.pop("ROS_DOMAIN_ID", None)
        else:
            os.environ["ROS_DOMAIN_ID"] = saved


@contextmanager
def output_to(path: Path) -> Iterator[None]:
    """Send this process's stdout and stderr (file descriptors 1 and 2, so native code's
    output and a crash's traceback too) to ``path`` for the block."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    log = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    try:
        os.dup2(log, 1)
        os.dup2(log, 2)
        faulthandler.enable(file=sys.stderr)
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (log, *saved):
            os.close(fd)
