"""Finding every process a test session started, wherever it went: by ancestry and by a mark.

- Ancestry: the test process makes itself a child subreaper (Linux), so a process whose
  parent died (an orphan: a forked node, a foreign program's child, a packed process) is
  re-parented to it instead of to init, and stays among its descendants.
- Mark: ``COSIM_TEST_SESSION`` is set in the test process's environment, so every program
  it starts, and all that those start, carry it in /proc/PID/environ. (A process forked
  without exec shows its ancestor's environment of exec time, without the mark; ancestry
  finds those.)

Adopted orphans that end stay zombies of the test process until it exits: they are not
reaped here, since a test's own Popen may still want its child's exit status.
"""

from __future__ import annotations

import ctypes
import os
import uuid

import psutil

MARK_ENV = "COSIM_TEST_SESSION"
MARK = uuid.uuid4().hex  # this session's, even inside a session (pytester) that set its own
PR_SET_CHILD_SUBREAPER = 36
PR_GET_CHILD_SUBREAPER = 37


def become_subreaper() -> bool:
    """Make this process adopt the orphans among its descendants; True if it now does."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
        flag = ctypes.c_int(0)
        libc.prctl(PR_GET_CHILD_SUBREAPER, ctypes.byref(flag), 0, 0, 0)
        return flag.value == 1
    except (OSError, AttributeError):
        return False


def mark_this_session() -> None:
    """Set the mark that every program started from now on inherits."""
    os.environ[MARK_ENV] = MARK


def carries_mark(proc: psutil.Process, mark: str = MARK) -> bool:
    """Whether ``proc``'s environment has this session's mark."""
    try:
        return proc.environ().get(MARK_ENV) == mark
    except (psutil.Error, OSError):
        return False


def alive(proc: psutil.Process) -> bool:
    """Running and not a zombie."""
    try:
        return proc.is_running() and proc.status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


def session_processes() -> list[psutil.Process]:
    """Live processes of this session (this one excepted): its descendants (orphans
    included, adopted by the subreaper) and every process carrying the mark."""
    me = psutil.Process()
    found = {p.pid: p for p in me.children(recursive=True)}
    for proc in psutil.process_iter():
        if proc.pid != me.pid and proc.pid not in found and carries_mark(proc):
            found[proc.pid] = proc
    return [p for p in found.values() if alive(p)]
