"""Tie a child process's life to its parent's (Linux parent-death signal)."""

from __future__ import annotations

import ctypes
import os
import signal

PR_SET_PDEATHSIG = 1
PR_SET_NAME = 15


def process_name(node: str) -> str:
    """The name a node's process shows in ps, top and psutil: 'cosim:<node>' (15 bytes)."""
    return f"cosim:{node}".encode()[:15].decode(errors="ignore")


def name_this_process(node: str) -> None:
    """Give this process the name ``process_name(node)`` (Linux only; elsewhere nothing)."""
    try:
        ctypes.CDLL(None).prctl(PR_SET_NAME, process_name(node).encode(), 0, 0, 0)
    except (OSError, AttributeError):
        pass


def die_with_parent(sig: int = signal.SIGTERM) -> None:
    """Ask the kernel to send ``sig`` to this process when its parent dies (Linux only)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, sig, 0, 0, 0)
    except (OSError, AttributeError):
        pass  # not Linux: the runtime's parent-pid watchdog still applies
    expected = os.environ.get("COSIM_PARENT_PID")
    if expected and os.getppid() != int(expected):
        os._exit(1)  # the parent died before the signal was armed


def started_by_orchestrator() -> bool:
    """Whether an orchestrator started this process (it sets ``COSIM_PARENT_PID`` for the
    nodes it spawns or forks); only those die with their parent."""
    return bool(os.environ.get("COSIM_PARENT_PID"))
