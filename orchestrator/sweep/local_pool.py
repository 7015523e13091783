"""The embedded backend: worker processes on this machine, one run at a time each.

Workers are forked from the sweep process (which has loaded the scenario, so its imports
are shared) and serve runs one after another over a pipe; in-process runs reuse a worker,
multi-process runs get a fresh one each (its node processes are forked from it, which
needs a process where rclpy was never loaded). A worker that dies is recorded as the
run's crash and replaced; one that runs past the timeout is stopped (SIGTERM: the run
cleans up, then SIGKILL for its whole process tree) and replaced. The standard library's
pools cannot do either: a dead worker breaks a ProcessPoolExecutor for every later task,
and neither pool can stop one task.

Each worker is a session of its own, as the orchestrator's node processes are: Ctrl-C in
the terminal reaches only the sweep, which stops the workers in order, and where the
kernel schedules by session (autogroup, the Linux default) every worker gets the CPU share
a run started alone would get, instead of the whole sweep sharing one. Workers die with
the sweep (parent-death signal).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from typing import Any

import psutil

from orchestrator.lockstep.supervisor import escalate, signals_ignored
from orchestrator.sweep.combinations import RunSpec
from orchestrator.sweep.one_run import base_record, find_run_dir, last_log_line, run_logged
from runtime.parent import die_with_parent

OnRecord = Callable[[dict[str, Any]], None]
POLL_S = 0.1
STOP_GRACE_S = 10.0  # a stopped run's time to stop its nodes and write its manifest
RESIGNAL_S = 1.0


@dataclass
class _Worker:
    """A worker process, the run it is on (None when idle) and how many it has done."""

    process: multiprocessing.Process
    conn: Connection
    spec: RunSpec | None = None
    started: float = 0.0
    done: int = 0


class LocalPool:
    """Runs specs on ``jobs`` worker processes; a record per run, whatever happens to it.

    ``timeout_s``: a run still going after this long is stopped and recorded as 'timeout'.
    ``runs_per_worker``: 1 gives every run a fresh process (multi-process runs); None
    reuses workers.
    """

    def __init__(self, jobs: int, timeout_s: float | None, runs_per_worker: int | None = None):
        self.jobs = max(1, jobs)
        self.timeout_s = timeout_s
        self.runs_per_worker = runs_per_worker
        self._context = multiprocessing.get_context("fork")
        self._workers: list[_Worker] = []

    def run(self, specs: list[RunSpec], on_record: OnRecord,
            on_poll: Callable[[], None] = lambda: None) -> None:
        """Run every spec, calling ``on_record`` with each run's record as it finishes.

        Ctrl-C (KeyboardInterrupt) stops every worker and the runs they are on, then
        propagates; the runs that finished before it were recorded.
        """
        pending = deque(specs)
        try:
            while pending or self._busy():
                while pending and len(self._busy()) < self.jobs:
                    self._assign(pending.popleft())
                busy = self._busy()
                wait([w.conn for w in busy] + [w.process.sentinel for w in busy],
                     timeout=POLL_S)
                for worker in busy:
                    record = self._check(worker)
                    if record is not None:
                        on_record(record)
                on_poll()
        except KeyboardInterrupt:
            with signals_ignored():  # a second Ctrl-C must not leave processes behind
                for record in self._stop(list(self._workers)):
                    on_record(record)
            raise
        finally:
            self._retire_all()

    def _busy(self) -> list[_Worker]:
        return [w for w in self._workers if w.spec is not None]

    def _assign(self, spec: RunSpec) -> None:
        """Give a run to an idle worker, starting one when none is idle."""
        idle = [w for w in self._workers if w.spec is None]
        worker = idle[0] if idle else self._start_worker()
        try:
            worker.conn.send(spec.as_dict())
        except OSError:  # an idle worker that died: replace it
            worker.process.join(1)
            self._forget(worker)
            worker = self._start_worker()
            worker.conn.send(spec.as_dict())
        worker.spec, worker.started = spec, time.monotonic()

    def _start_worker(self) -> _Worker:
        sys.stdout.flush()
        sys.stderr.flush()
        ours, theirs = self._context.Pipe()
        others = [w.conn.fileno() for w in self._workers if not w.conn.closed]
        process = self._context.Process(target=_worker_main,
                                        args=(theirs, os.getpid(), others),
                                        name="cosim-sweep-worker")
        process.start()
        theirs.close()
        worker = _Worker(process, ours)
        self._workers.append(worker)
        return worker

    def _check(self, worker: _Worker) -> dict[str, Any] | None:
        """The worker's record when its run is over (finished, crashed or timed out)."""
        spec = worker.spec
        record = _receive(worker.conn)
        if record is not None:
            worker.spec, worker.done = None, worker.done + 1
            if self.runs_per_worker and worker.done >= self.runs_per_worker:
                self._retire(worker)
            return record
        if not worker.process.is_alive():
            worker.process.join()
            self._forget(worker)
            return self._lost(spec, worker, "crashed", died_how(worker.process.exitcode))
        elapsed = time.monotonic() - worker.started
        if self.timeout_s is not None and elapsed > self.timeout_s:
            finished = self._stop([worker])
            if finished:  # it finished as the time ran out
                return finished[0]
            return self._lost(spec, worker, "timeout",
                              f"still running after {self.timeout_s:g} s (--timeout): stopped")
        return None

    def _lost(self, spec: RunSpec, worker: _Worker, status: str, why: str) -> dict[str, Any]:
        """The record of a run whose worker did not report it."""
        record = base_record(spec)
        last = last_log_line(spec)
        run_dir = find_run_dir(spec)
        record.update(status=status, wall_s=time.monotonic() - worker.started,
                      run_dir=str(run_dir) if run_dir else None,
                      error=f"{why}" + (f"; its last output: {last}" if last else ""))
        return record

    def _stop(self, workers: list[_Worker]) -> list[dict[str, Any]]:
        """Stop workers and everything they started: SIGTERM (each run stops its nodes and
        keeps what it recorded), then SIGKILL for whatever is left of their trees. Returns
        the records of runs that finished meanwhile (a run that was saving its results when
        the signal came, with signals ignored, finishes and reports)."""
        trees: dict[int, psutil.Process] = {}
        for worker in workers:
            trees.update(_tree(worker.process.pid))
            _signal(worker.process.pid, signal.SIGTERM)
        records = []
        deadline = time.monotonic() + STOP_GRACE_S
        signalled = time.monotonic()
        waiting = list(workers)
        while waiting and time.monotonic() < deadline:
            wait([w.conn for w in waiting] + [w.process.sentinel for w in waiting],
                 timeout=POLL_S)
            for worker in list(waiting):
                record = _receive(worker.conn)
                if record is not None:
                    records.append(record)
                    worker.conn.close()  # the worker's next wait for work ends: it exits
                if worker.conn.closed or not worker.process.is_alive():
                    waiting.remove(worker)
            for worker in waiting:  # children started during the grace period count too
                trees.update(_tree(worker.process.pid))
            if time.monotonic() - signalled > RESIGNAL_S:
                # a run ignores signals while it saves its results: one sent then is lost
                for worker in waiting:
                    _signal(worker.process.pid, signal.SIGTERM)
                signalled = time.monotonic()
        for worker in workers:
            worker.process.join(max(0.0, deadline - time.monotonic()))
        _, alive = psutil.wait_procs(list(trees.values()), timeout=0.5)
        escalate(alive, steps=((signal.SIGKILL, 5.0),))
        for worker in workers:
            worker.process.join(5)
            self._forget(worker)
        return records

    def _retire(self, worker: _Worker) -> None:
        """Let an idle worker exit."""
        try:
            worker.conn.send(None)
        except OSError:
            pass
        worker.process.join(10)
        if worker.process.is_alive():
            self._stop([worker])
        self._forget(worker)

    def _retire_all(self) -> None:
        for worker in list(self._workers):
            self._retire(worker)

    def _forget(self, worker: _Worker) -> None:
        if not worker.conn.closed:
            worker.conn.close()
        if worker in self._workers:
            self._workers.remove(worker)


def _worker_main(conn: Connection, parent: int, others: list[int]) -> None:
    """A worker: take a spec, run it with its output in its run.log, send the record.

    ``others``: the sweep's ends of the other workers' pipes, inherited through the fork;
    closed, so that a worker whose pipe the sweep closes sees the end of it."""
    for fd in others:
        os.close(fd)
    os.setsid()  # the terminal's Ctrl-C goes to the sweep, which stops us in order
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _interrupt)
    die_with_parent(signal.SIGTERM)
    if os.getppid() != parent:
        return
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError, KeyboardInterrupt):
            return
        if message is None:
            return
        try:
            record = run_logged(message)
        except KeyboardInterrupt:
            return  # stopped: the sweep records it
        with signals_ignored():  # never half a record on the pipe
            conn.send(record)


def _receive(conn: Connection) -> dict[str, Any] | None:
    """A record waiting on a worker's pipe, else None."""
    try:
        return conn.recv() if not conn.closed and conn.poll() else None
    except (EOFError, OSError):
        return None


def _interrupt(signum, _frame):
    raise KeyboardInterrupt


def _tree(pid: int) -> dict[int, psutil.Process]:
    """A process and all its descendants."""
    try:
        root = psutil.Process(pid)
        return {p.pid: p for p in [root, *root.children(recursive=True)]}
    except psutil.Error:
        return {}


def _signal(pid: int, sig: int) -> None:
    try:
        os.kill(pid, sig)
    except OSError:
        pass


def died_how(exitcode: int | None) -> str:
    """'the run's process died (killed by SIGKILL)' or '... (exit code 7)'."""
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        return f"the run's process died (killed by {name})"
    return f"the run's process died (exit code {exitcode})"
