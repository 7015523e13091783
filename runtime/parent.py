"""Tie a child process's life to its parent's (Linux parent-death signal)."""

from __future__ import annotations

import ctypes
import os
import signal
import threading
import time

PR_SET_PDEATHSIG = 1
PR_SET_NAME = 15
WATCH_S = 0.2  # how often the watchdog looks at the parent
GRACE_S = 5.0  # how long a node whose parent died has to stop on its own, before SIGKILL


def process_name(node: str) -> str:
    """The name a node's process shows in ps, top and psutil: 'cosim:<node>' (15 bytes)."""
    return f"cosim:{node}".encode()[:15].decode(errors="ignore")


def name_this_process(node: str) -> None:
    """Give this process the name ``process_name(node)`` (Linux only; elsewhere nothing)."""
    try:
        ctypes.CDLL(None).prctl(PR_SET_NAME, process_name(node).encode(), 0, 0, 0)
    except (OSError, AttributeError):
        pass


def die_with_parent(sig: int = signal.SIGTERM, watchdog: bool = False) -> None:
    """Ask the kernel to send ``sig`` to this process when its parent dies (Linux only).

    The parent named by ``COSIM_PARENT_PID`` may die before the signal is armed (between
    fork and here): the parent is checked again after arming, and this process exits at
    once if it is gone. With ``watchdog`` (node processes, which fork nothing), a thread
    also watches the parent: once it is gone, it sends ``sig`` again (a handler may have
    been busy or the signal missed) and, ``GRACE_S`` later, SIGKILL, so that a process
    that cannot act on the signal (a hung step, a transport that blocks on close) goes too.
    """
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, sig, 0, 0, 0)
    except (OSError, AttributeError):
        pass  # not Linux: the runtime's parent-pid watchdog still applies
    expected = os.environ.get("COSIM_PARENT_PID")
    if expected and os.getppid() != int(expected):
        os._exit(1)  # the parent died before the signal was armed
    if watchdog and expected:
        threading.Thread(target=_watch, args=(int(expected), sig), daemon=True,
                         name="cosim-parent-watchdog").start()


def _watch(parent: int, sig: int) -> None:
    """Wait for the parent's death, then make sure this process ends (see die_with_parent)."""
    # the process's signals (stop requests, the slow-step alarm) are the main thread's
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGALRM, signal.SIGINT, signal.SIGTERM})
    while os.getppid() == parent:
        time.sleep(WATCH_S)
    os.kill(os.getpid(), sig)
    time.sleep(GRACE_S)
    os.kill(os.getpid(), signal.SIGKILL)


def started_by_orchestrator() -> bool:
    """Whether an orchestrator started this process (it sets ``COSIM_PARENT_PID`` for the
    nodes it spawns or forks); only those die with their parent."""
    return bool(os.environ.get("COSIM_PARENT_PID"))
