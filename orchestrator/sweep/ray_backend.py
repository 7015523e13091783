"""The Ray backend: every run a Ray task, on any Ray cluster (``--ray ADDRESS|auto|local``).

A task asks for as many CPUs as its run has processes (1 in-process; the nodes and the
orchestrator otherwise), so Ray never packs more runs onto a machine than it has cores.
The task is the same ``run_logged`` a local worker calls; a multi-process run's task gets
a fresh worker process (``max_calls=1``: its nodes are started from it) and leases a ROS
domain id of the machine it lands on. Ray places, queues and retries nothing on our
behalf beyond that (``max_retries=0``: a crashed run is a result, not something to hide).

Tasks are submitted no faster than the cluster can start them, so a task's time since
submission is its run time: a run past ``--timeout`` is cancelled (KeyboardInterrupt in
the task, so the run stops its nodes and keeps what it recorded), then killed. Ctrl-C
does the same for every task in flight. cosim, the scenario and its files must be at the
same paths on every node of the cluster, and ``--out`` on storage they share.
"""

from __future__ import annotations

import logging
import socket
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from orchestrator.lockstep.supervisor import signals_ignored
from orchestrator.sweep.combinations import RunSpec
from orchestrator.sweep.one_run import base_record, find_run_dir, last_log_line, run_logged

OnRecord = Callable[[dict[str, Any]], None]
POLL_S = 0.1
STOP_GRACE_S = 10.0
CAPACITY_REFRESH_S = 5.0
CONNECT_TIMEOUT_S = 5.0


class RayPool:
    """Runs specs as Ray tasks on the cluster at ``address`` ('auto': the one this machine
    belongs to; 'local': a Ray started for this sweep alone, with ``jobs`` CPUs).

    ``jobs`` (optional) caps the runs in flight; ``timeout_s`` stops a run that goes on
    longer.
    """

    def __init__(self, address: str, jobs: int | None, timeout_s: float | None):
        self.address = address
        self.jobs = jobs
        self.timeout_s = timeout_s

    def connect(self) -> None:
        """Join (or, for 'local', start) the Ray cluster."""
        import ray

        if self.address == "local":
            ray.init(num_cpus=self.jobs, include_dashboard=False, log_to_driver=False,
                     logging_level=logging.WARNING)
            return
        if self.address != "auto":
            _check_reachable(self.address)  # else Ray retries for minutes
        ray.init(address=self.address, log_to_driver=False, logging_level=logging.WARNING)

    def close(self) -> None:
        """Leave the cluster (a 'local' one stops with it)."""
        import ray

        ray.shutdown()

    def check_fits(self, processes: int) -> None:
        """ValueError when no node of the cluster has ``processes`` CPUs for one run."""
        if not self._capacity(processes):
            raise ValueError(f"no node of the Ray cluster at {self.address} has "
                             f"{processes} CPUs, which one run needs (one per process); run "
                             "in-process, or add bigger nodes")

    def run(self, specs: list[RunSpec], on_record: OnRecord,
            on_poll: Callable[[], None] = lambda: None) -> None:
        """Run every spec as a task, calling ``on_record`` with each run's record."""
        import ray

        pending = deque(specs)
        flight: dict[Any, tuple[RunSpec, float]] = {}  # ref -> (spec, submitted)
        stopping: dict[Any, tuple[str, float]] = {}  # ref -> (why, when cancelled)
        tasks = {True: ray.remote(max_retries=0)(run_logged),
                 False: ray.remote(max_retries=0, max_calls=1)(run_logged)}
        capacity, measured = 0, 0.0
        try:
            while pending or flight:
                if time.monotonic() - measured > CAPACITY_REFRESH_S:
                    capacity, measured = self._slots(specs[0].processes), time.monotonic()
                while pending and len(flight) < capacity:
                    spec = pending.popleft()
                    ref = tasks[spec.in_process].options(
                        num_cpus=spec.processes, name=f"cosim:{spec.run_id}").remote(
                        spec.as_dict())
                    flight[ref] = (spec, time.monotonic())
                if not flight:
                    continue
                ready, _ = ray.wait(list(flight), num_returns=len(flight), timeout=POLL_S)
                for ref in ready:
                    spec, submitted = flight.pop(ref)
                    why = stopping.pop(ref, None)
                    on_record(self._record(ref, spec, submitted, why))
                self._timeouts(flight, stopping)
                on_poll()
        except KeyboardInterrupt:
            with signals_ignored():
                self._cancel_all(flight)
            raise

    def _slots(self, processes: int) -> int:
        """How many runs the cluster can hold at once (capped by ``jobs``)."""
        slots = self._capacity(processes)
        return max(1, min(slots, self.jobs) if self.jobs else slots)

    @staticmethod
    def _capacity(processes: int) -> int:
        import ray

        return sum(int(node["Resources"].get("CPU", 0) // processes)
                   for node in ray.nodes() if node.get("Alive"))

    def _record(self, ref, spec: RunSpec, submitted: float,
                why: tuple[str, float] | None) -> dict[str, Any]:
        """The task's record, or one saying how it was lost (crashed, timed out)."""
        import ray
        from ray.exceptions import TaskCancelledError, WorkerCrashedError

        try:
            return ray.get(ref)
        except (TaskCancelledError, WorkerCrashedError, ray.exceptions.RayError) as exc:
            record = base_record(spec)
            if why is not None:
                status, error = "timeout", why[0]
            elif isinstance(exc, WorkerCrashedError):
                status, error = "crashed", "the Ray worker running the run died"
            else:
                status, error = "error", f"{type(exc).__name__}: {_first_line(exc)}"
            last = last_log_line(spec)
            run_dir = find_run_dir(spec)
            record.update(status=status, wall_s=time.monotonic() - submitted,
                          run_dir=str(run_dir) if run_dir else None,
                          error=error + (f"; its last output: {last}" if last else ""))
            return record

    def _timeouts(self, flight: dict, stopping: dict) -> None:
        """Cancel runs past the timeout; kill those that do not stop within the grace."""
        import ray

        now = time.monotonic()
        for ref, (_, submitted) in flight.items():
            if ref in stopping:
                if now - stopping[ref][1] > STOP_GRACE_S:
                    ray.cancel(ref, force=True)
            elif self.timeout_s is not None and now - submitted > self.timeout_s:
                stopping[ref] = (f"still running after {self.timeout_s:g} s (--timeout): "
                                 "stopped", now)
                ray.cancel(ref)

    def _cancel_all(self, flight: dict) -> None:
        """Ctrl-C: interrupt every task in flight, then kill what did not stop."""
        import ray

        for ref in flight:
            ray.cancel(ref)
        refs = list(flight)
        deadline = time.monotonic() + STOP_GRACE_S
        while refs and time.monotonic() < deadline:
            _, refs = ray.wait(refs, num_returns=len(refs), timeout=0.2)
        for ref in refs:
            ray.cancel(ref, force=True)
        if refs:
            ray.wait(refs, num_returns=len(refs), timeout=5)


def _check_reachable(address: str) -> None:
    """ConnectionError unless something listens at ``host:port`` (ray://host:port too)."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        raise ValueError(f"{address!r} is not host:port, auto or local")
    try:
        socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        raise ConnectionError(f"nothing answers at {address} ({exc}); is the Ray head "
                              "running there (ray start --head)?") from None


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else ""
