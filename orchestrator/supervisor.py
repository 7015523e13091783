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
from dataclasses import dataclass, field
from pathlib import Path

import psutil

from nodes.parent import PR_SET_PDEATHSIG

SIGINT_TIMEOUT_S = 3.0
SIGTERM_TIMEOUT_S = 2.0


def _arm_parent_death() -> None:  # runs in the child between fork and exec
    import ctypes

    ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)


@dataclass
class NodeProcess:
    """A spawned node: its process, log file and the psutil handle for CPU and memory."""

    name: str
    popen: subprocess.Popen
    log_path: Path
    ps: psutil.Process | None = None
    peak_rss: int = 0
    cpu_s: float = 0.0
    tree: set[int] = field(default_factory=set)

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
        except (psutil.Error, OSError):
            pass


class Supervisor:
    """Starts node processes and stops them all, whatever happens."""

    def __init__(self, log_dir: Path):
        self.log_dir = log_dir
        self.procs: dict[str, NodeProcess] = {}

    def spawn(self, name: str, argv: list[str], env: dict[str, str] | None = None,
              cwd: Path | None = None) -> NodeProcess:
        """Start one node, its output going to ``<log dir>/<name>.log``."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        log_path = self.log_dir / f"{name}.log"
        full_env = dict(os.environ if env is None else env)
        full_env["COSIM_PARENT_PID"] = str(os.getpid())
        full_env.setdefault("PYTHONUNBUFFERED", "1")
        argv = launch_prefix(name, full_env) + list(argv)
        with open(log_path, "ab") as log:
            popen = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, env=full_env, cwd=cwd,
                                     start_new_session=True, preexec_fn=_arm_parent_death)
        proc = NodeProcess(name, popen, log_path)
        try:
            proc.ps = psutil.Process(popen.pid)
        except psutil.Error:
            proc.ps = None
        self.procs[name] = proc
        return proc

    def dead(self) -> list[NodeProcess]:
        """Nodes whose process has exited."""
        return [p for p in self.procs.values() if p.popen.poll() is not None]

    def sample(self, with_children: bool = False) -> None:
        """Sample CPU and memory of every live node (children too: costly, so on request)."""
        for proc in self.procs.values():
            if proc.popen.poll() is None:
                proc.sample(with_children)

    def shutdown(self) -> None:
        """Stop every node tree: SIGINT, then SIGTERM, then SIGKILL; never interrupted."""
        with signals_ignored():
            self.sample(with_children=True)
            pending = [ps for p in self.procs.values() for ps in self._tree(p)]
            for sig, timeout in ((signal.SIGINT, SIGINT_TIMEOUT_S),
                                 (signal.SIGTERM, SIGTERM_TIMEOUT_S), (signal.SIGKILL, 5.0)):
                pending = [ps for ps in pending if _alive(ps)]
                if not pending:
                    break
                for ps in pending:
                    _signal(ps, sig)
                    _signal(ps, signal.SIGCONT)  # a stopped process must run to see it
                _, pending = psutil.wait_procs(pending, timeout=timeout)
            for proc in self.procs.values():
                try:
                    proc.popen.wait(timeout=1.0)
                except subprocess.TimeoutExpired:
                    pass

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


def launch_prefix(name: str, env: dict[str, str]) -> list[str]:
    """The command that wraps node ``name``'s process, from ``COSIM_LAUNCH_PREFIX``.

    A JSON object mapping node names to a command line, e.g.
    ``{"lidar": "ip netns exec cosim_b"}``: how tests place a node in another network
    namespace (a stand-in for another host). The command must exec the node (keep its pid).
    """
    import json
    import shlex

    prefixes = json.loads(env.get("COSIM_LAUNCH_PREFIX") or "{}")
    return shlex.split(prefixes.get(name, ""))


def node_argv(scenario_file: Path, kind: str, name: str, run_dir: Path | None,
              overrides: dict) -> list[str]:
    """The command line that runs node ``name`` under this orchestrator."""
    import json

    argv = [sys.executable, "-m", "nodes.cli", kind, "--scenario", str(scenario_file),
            "--node", name]
    if run_dir is not None:
        argv += ["--run-dir", str(run_dir)]
    for key, value in overrides.items():
        argv += ["--set", f"{key}={json.dumps(value)}"]
    return argv
