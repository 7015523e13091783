"""The suite's own guard against left-over processes (tests/leftovers.py, used by conftest.py)
finds orphans: a process forked without exec whose parent ended (it carries no mark, so only
ancestry, through the subreaper, finds it) and a program whose parent ended (it carries the
session's mark)."""

from __future__ import annotations

import os
import subprocess
import time

import psutil

from tests.leftovers import carries_mark, session_processes


def orphaned_fork() -> int:
    """The pid of a forked grandchild (no exec) whose parent has exited."""
    r, w = os.pipe()
    child = os.fork()
    if child == 0:
        try:
            grandchild = os.fork()
            if grandchild == 0:
                os.close(w)  # the parent reads the pipe to its end
                time.sleep(120)
            else:
                os.write(w, str(grandchild).encode())
        finally:
            os._exit(0)
    os.close(w)
    os.waitpid(child, 0)
    with os.fdopen(r) as pipe:
        return int(pipe.read())


def orphaned_program() -> int:
    """The pid of a program started by a shell that has exited."""
    shell = subprocess.run(["sh", "-c", "sleep 120 >/dev/null 2>&1 & echo $!"],
                           capture_output=True, text=True, timeout=60, check=True)
    return int(shell.stdout)


def test_the_guard_finds_orphaned_forks_and_programs():
    pids = [orphaned_fork(), orphaned_program()]
    procs = [psutil.Process(pid) for pid in pids]
    try:
        found = {p.pid for p in session_processes()}
        assert set(pids) <= found, f"not found: {set(pids) - found}"
        forked, program = procs
        assert carries_mark(program) and not carries_mark(forked)
        assert all(p.ppid() == os.getpid() for p in procs)  # adopted by the test process
    finally:
        for proc in procs:
            proc.kill()
        psutil.wait_procs(procs, timeout=30)
