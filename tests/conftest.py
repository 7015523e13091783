"""Test-suite isolation: a ROS domain of its own per test run, and no process left behind
(found by ancestry and by the session's mark: tests/leftovers.py)."""

from __future__ import annotations

import os
import random

import psutil
import pytest

import nodes  # noqa: F401 - provides the node kinds to the plan (plan.kinds)
from tests.leftovers import alive, become_subreaper, mark_this_session, session_processes

# One domain per test run, chosen before anything imports rclpy; children inherit it.
DOMAIN = os.environ.get("COSIM_TEST_DOMAIN") or str(random.SystemRandom().randint(1, 100))
os.environ["ROS_DOMAIN_ID"] = DOMAIN
os.environ.setdefault("MUJOCO_GL", "egl")
mark_this_session()
become_subreaper()


@pytest.fixture(autouse=True)
def no_process_left_behind(request):
    """Fail the test that leaves any process of the run alive (and kill what it left)."""
    yield
    left = session_processes()
    if left:
        _, left = psutil.wait_procs(left, timeout=5)
    if left:
        names = [_describe(p) for p in left if alive(p)]
        for proc in left:
            try:
                proc.kill()
            except psutil.Error:
                pass
        if names:
            pytest.fail(f"{request.node.nodeid} left processes behind: {names}")


def _describe(proc: psutil.Process) -> str:
    """'PID name command line' of a left-over process (what is still readable)."""
    try:
        return f"{proc.pid} {proc.name()} {' '.join(proc.cmdline()[:6])}"
    except psutil.Error:
        return str(proc.pid)


@pytest.fixture
def ros_node():
    """A plain rclpy node and its executor in the test's process, as a user's script has."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("cosim_test_user", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    yield node, executor
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown(context=context)
