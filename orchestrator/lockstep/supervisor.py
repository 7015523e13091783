"""Process supervision: spawn node processes, notice deaths, and shut whole trees down.

Shutdown escalates like ros2 launch: SIGINT, then SIGTERM, then SIGKILL, each after a
timeout, applied to every process of each node's tree (found with psutil).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import psutil

from plan.options import RunOptions
from runtime.parent import PR_SET_PDEATHSIG, die_with_parent, name_this_process

ESCALATION = ((signal.SIGINT, 3.0), (signal.SIGTERM, 2.0), (signal.SIGKILL, 5.0))
"""How a process tree is stopped, like ros2 launch: each signal, then that many seconds'
wait for the processes still alive, before the next."""


def _arm_parent_death(parent: int) -> None:  # runs in the child between fork and exec
    import ctypes

    ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    if os.getppid() != parent:  # the parent died before the signal was armed: no program
        os._exit(1)


class ForkedChild:
    """The part of ``subprocess.Popen`` the supervisor uses, for a child made by ``os.fork``."""

    def __init__(self, pid: int):
        self.pid = pid
        self.returncode: int | None = None

    def poll(self) -> int | None:
        """The exit code (negative: killed by that signal), or None while it runs."""
        if self.returncode is None:
            try:
                pid, status = os.waitpid(self.pid, os.WNOHANG)
            except ChildProcessError:  # reaped elsewhere (psutil.wait_procs): exit unknown
                self.returncode = 0
                return self.returncode
            if pid:
                self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        """Wait for the exit; subprocess.TimeoutExpired after ``timeout`` seconds."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            if deadline is not None and time.monotonic() > deadline:
                raise subprocess.TimeoutExpired(str(self.pid), timeout)
            time.sleep(0.01)
        return self.returncode


@dataclass
class NodeProcess:
    """A spawned node: its process, log file and the psutil handle for CPU and memory."""

    name: str
    popen: subprocess.Popen | ForkedChild
    log_path: Path
    ps: psutil.Process | None = None
    started: str = "exec"  # 'fork' of the orchestrator, or 'exec' of a fresh program
    peak_rss: int = 0
    pss: int = 0  # proportional set size when last sampled with children (``memory_of``)
    uss: int = 0  # unique set size, likewise
    cpu_s: float = 0.0
    tree: set[int] = field(default_factory=set)
    members: tuple[str, ...] = ()  # the nodes packed into this process (default: its name)

    def __post_init__(self) -> None:
        self.members = self.members or (self.name,)

    def exit_text(self) -> str:
        """'exit code 3' or 'killed by signal SIGKILL'."""
        code = self.popen.returncode
        if code is None:
            return "still running"
        if code < 0:
            return f"killed by signal {signal.Signals(-code).name}"
        return f"exit code {code}"

    def log_tail(self, lines: int = 15) -> str:
        """The last lines of the node's log."""
        try:
            text = self.log_path.read_text(errors="replace").splitlines()
        except OSError:
            return "(no log)"
        return "\n".join(text[-lines:]) or "(log is empty)"

    def sample(self, with_children: bool = False) -> None:
        """Update CPU time and peak memory (best effort; the process may be gone)."""
        try:
            procs = [self.ps] if self.ps else []
            if with_children and self.ps:
                procs += self.ps.children(recursive=True)
            self.tree.update(p.pid for p in procs)
            rss = sum(p.memory_info().rss for p in procs)
            cpu = sum(sum(p.cpu_times()[:2]) for p in procs)
            self.peak_rss = max(self.peak_rss, rss)
            self.cpu_s = max(self.cpu_s, cpu)
            if with_children:  # the run's end, every process alive: one instant for all
                shares = [memory_of(p.pid) for p in procs]
                self.pss = sum(pss for pss, _ in shares)
                self.uss = sum(uss for _, uss in shares)
        except (psutil.Error, OSError):
            pass


def memory_of(pid: int) -> tuple[int, int]:
    """(PSS, USS) of a process in bytes, from ``/proc/PID/smaps_rollup``: its resident
    pages with each shared page divided among the processes that map it, and the pages no
    other process maps. Forked node processes share the orchestrator's pages copy-on-write,
    so their RSS summed counts those pages once per process; PSS summed counts them once.
    (0, 0) where the file cannot be read."""
    fields = {}
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            for line in f:
                key, _, rest = line.partition(":")
                if key in ("Pss", "Private_Clean", "Private_Dirty"):
                    fields[key] = int(rest.split()[0]) * 1024
    except (OSError, ValueError, IndexError):
        return 0, 0
    return fields.get("Pss", 0), fields.get("Private_Clean", 0) + fields.get("Private_Dirty", 0)


class Supervisor:
    """Starts node processes and stops them all, whatever happens."""

    def __init__(self, log_dir: Path):
        self.log_dir = log_dir
        self.procs: dict[str, NodeProcess] = {}
        self.own_memory: tuple[int, int] = (0, 0)  # this process's (PSS, USS) at the end

    def spawn(self, name: str, argv: list[str], env: dict[str, str] | None = None,
              cwd: Path | None = None, prefix: list[str] | None = None) -> NodeProcess:
        """Start one node, its output going to ``<log dir>/<name>.log``; ``prefix`` wraps
        the command (gdb, valgrind, ``ip netns exec``: it must exec the node)."""
        log_path = self._log_path(name)
        full_env = dict(os.environ if env is None else env)
        full_env["COSIM_PARENT_PID"] = str(os.getpid())
        full_env.setdefault("PYTHONUNBUFFERED", "1")
        argv = list(prefix or []) + list(argv)
        with open(log_path, "ab") as log:
            popen = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, env=full_env, cwd=cwd,
                                     start_new_session=True,
                                     preexec_fn=partial(_arm_parent_death, os.getpid()))
        return self._register(NodeProcess(name, popen, log_path))

    def fork(self, name: str, target: Callable[[], int]) -> NodeProcess:
        """Start one node as a fork of this process running ``target`` (its exit code),
        output to ``<log dir>/<name>.log``. The child inherits every module and the loaded
        scenario, so it skips the imports and parsing a fresh interpreter would repeat
        (most of a node's start-up). Only call it while :func:`fork_is_safe`."""
        log_path = self._log_path(name)
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        log_fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        parent = os.getpid()
        pid = os.fork()
        if pid == 0:
            _forked_child(name, log_fd, parent, target)  # never returns
        os.close(log_fd)
        return self._register(NodeProcess(name, ForkedChild(pid), log_path, started="fork"))

    def _log_path(self, name: str) -> Path:
        self.log_dir.mkdir(parents=True, exist_ok=True)
        return self.log_dir / f"{name}.log"

    def _register(self, proc: NodeProcess) -> NodeProcess:
        """Keep a started node, with its psutil handle (None if it is already gone)."""
        try:
            proc.ps = psutil.Process(proc.popen.pid)
        except psutil.Error:
            proc.ps = None
        self.procs[proc.name] = proc
        return proc

    def processes(self) -> list[NodeProcess]:
        """Every started process once (packed nodes share one)."""
        return list({id(p): p for p in self.procs.values()}.values())

    def pack(self, proc: NodeProcess, members: list[str]) -> None:
        """Register a process that runs several nodes under each of their names."""
        proc.members = tuple(members)
        for name in members:
            self.procs[name] = proc

    def dead(self) -> list[NodeProcess]:
        """Processes that have exited."""
        return [p for p in self.processes() if p.popen.poll() is not None]

    def sample(self, with_children: bool = False) -> None:
        """Sample CPU and memory of every live node (children too: costly, so on request)."""
        for proc in self.processes():
            if proc.popen.poll() is None:
                proc.sample(with_children)

    def shutdown(self) -> None:
        """Stop every node tree: SIGINT, then SIGTERM, then SIGKILL; never interrupted."""
        with signals_ignored():
            self.sample(with_children=True)
            self.own_memory = memory_of(os.getpid())  # at the same instant as the nodes'
            pending = list({ps.pid: ps for p in self.processes()
                            for ps in self._tree(p)}.values())
            escalate(pending, on_gone=self._note_exit_codes)
            for proc in self.processes():
                try:
                    proc.popen.wait(timeout=1.0)
                except subprocess.TimeoutExpired:
                    pass

    def _note_exit_codes(self, gone: list[psutil.Process]) -> None:
        """psutil reaps the children it waits for: keep the exit codes it saw."""
        codes = {ps.pid: ps.returncode for ps in gone if ps.returncode is not None}
        for proc in self.procs.values():
            if proc.popen.returncode is None and proc.popen.pid in codes:
                proc.popen.returncode = codes[proc.popen.pid]

    def _tree(self, proc: NodeProcess) -> list[psutil.Process]:
        procs = []
        for pid in sorted(proc.tree | {proc.popen.pid}):
            try:
                ps = psutil.Process(pid)
                procs.append(ps)
                procs.extend(ps.children(recursive=True))
            except psutil.Error:
                continue
        return list({p.pid: p for p in procs}.values())


def fork_is_safe() -> bool:
    """Whether this process may fork node processes: rclpy's native library is not loaded
    (its threads would be missing in the child), no zenoh session or Python thread runs.
    (The run option ``spawn='exec'`` always starts fresh interpreters instead.)"""
    if not hasattr(os, "fork"):
        return False
    zenoh_open = "runtime.transport.zenoh" in sys.modules  # imported only to open a session
    return (threading.active_count() == 1 and not zenoh_open
            and "rclpy._rclpy_pybind11" not in sys.modules)


def _forked_child(name: str, log_fd: int, parent: int, target: Callable[[], int]) -> None:
    """In a forked node: a session, log and name of its own, then ``target``; always exits."""
    code = 1
    try:
        os.setsid()
        name_this_process(name)
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        os.dup2(log_fd, 1)
        os.dup2(log_fd, 2)
        os.close(null)
        os.close(log_fd)
        sys.stdin = open(os.devnull)  # noqa: SIM115 - the process ends with os._exit
        sys.stdout = open(1, "w", buffering=1, closefd=False)  # noqa: SIM115
        sys.stderr = open(2, "w", buffering=1, closefd=False)  # noqa: SIM115
        for sig in (signal.SIGTERM, signal.SIGALRM):
            signal.signal(sig, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        import logging

        logging.getLogger().handlers.clear()  # the orchestrator's log file is not ours
        os.environ["COSIM_PARENT_PID"] = str(parent)
        die_with_parent(watchdog=True)
        code = target()
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    except BaseException:  # noqa: BLE001 - reported in the node's log, like an uncaught error
        import traceback

        traceback.print_exc()
    finally:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os._exit(code)


def escalate(procs: list[psutil.Process], steps: tuple[tuple[int, float], ...] = ESCALATION,
             on_gone: Callable[[list[psutil.Process]], None] | None = None
             ) -> list[psutil.Process]:
    """Stop ``procs``: each step's signal to those still alive, then its wait; returns the
    ones that outlived every step. ``on_gone`` sees each batch that exited (psutil reaps
    them: their exit codes are only there)."""
    pending = list(procs)
    for sig, timeout in steps:
        pending = [ps for ps in pending if _alive(ps)]
        if not pending:
            break
        for ps in pending:
            _signal(ps, sig)
            _signal(ps, signal.SIGCONT)  # a stopped process must run to see it
        gone, pending = psutil.wait_procs(pending, timeout=timeout)
        if on_gone is not None:
            on_gone(gone)
    return pending


def _signal(ps: psutil.Process, sig: int) -> None:
    try:
        ps.send_signal(sig)
    except psutil.Error:
        pass


@contextlib.contextmanager
def signals_ignored():
    """Ignore SIGINT and SIGTERM inside the block: shutdown and saving must not be cut short."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _alive(ps: psutil.Process) -> bool:
    try:
        return ps.is_running() and ps.status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


def node_argv(scenario_file: Path, kind: str, names: list[str], run_dir: Path | None,
              overrides: dict, options: RunOptions | None = None,
              plan: Path | None = None) -> list[str]:
    """The command line that runs the nodes ``names`` (one process) under this
    orchestrator; ``plan``: the checked plan it wrote (``write_checked_plan``), which the
    process takes instead of loading and checking the scenario again."""
    import json

    argv = [sys.executable, "-m", "runtime.cosim_node", kind,
            "--scenario", str(scenario_file)]
    for name in names:
        argv += ["--node", name]
    if run_dir is not None:
        argv += ["--run-dir", str(run_dir)]
    if options is not None and options.node_json() != RunOptions().node_json():
        argv += ["--run-options", options.node_json()]
    for key, value in overrides.items():
        argv += ["--set", f"{key}={json.dumps(value)}"]
    if plan is not None:
        argv += ["--plan", str(plan)]
    return argv


def write_checked_plan(scenario, path: Path) -> Path | None:
    """The checked scenario pickled at ``path`` (once per run: kept if already there) for the
    node processes this orchestrator execs: a process that loads the file itself checks the
    whole plan again (seconds at hundreds of robots, in every process). With it go the swarm
    world's models compiled here (``descriptions.swarm_world.hand_over``), which the process
    would otherwise build and compile again. None where it cannot be written (the processes
    then load the file)."""
    import pickle

    from descriptions.swarm_world import hand_over

    if path.exists():
        return path
    try:
        part = path.with_suffix(".part")
        models = hand_over(scenario.world) if scenario.world is not None else []
        part.write_bytes(pickle.dumps((scenario, models), protocol=pickle.HIGHEST_PROTOCOL))
        part.replace(path)
    except (OSError, pickle.PicklingError, TypeError, AttributeError):
        return None
    return path
