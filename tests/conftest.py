"""Test-suite isolation: a ROS domain of its own per test run, and no process left behind."""

from __future__ import annotations

import os
import random

import psutil
import pytest

import nodes  # noqa: F401 - provides the node kinds to the plan (plan.kinds)

# One domain per test run, chosen before anything imports rclpy; children inherit it.
DOMAIN = os.environ.get("COSIM_TEST_DOMAIN") or str(random.SystemRandom().randint(1, 100))
os.environ["ROS_DOMAIN_ID"] = DOMAIN
os.environ.setdefault("MUJOCO_GL", "egl")


def run_processes() -> list[psutil.Process]:
    """Processes of this test run: descendants of pytest, and node processes in our domain."""
    me = psutil.Process()
    found = {p.pid: p for p in me.children(recursive=True)}
    for proc in psutil.process_iter(["cmdline"]):
        cmdline = " ".join(proc.info["cmdline"] or [])
        if any(mark in cmdline for mark in ("runtime.cosim_node", "cosim-node",
                                            "orchestrator.cosim_orchestrate")):
            try:
                if proc.environ().get("ROS_DOMAIN_ID") == DOMAIN and proc.pid != me.pid:
                    found[proc.pid] = proc
            except psutil.Error:
                continue
    return [p for p in found.values() if _alive(p)]


def _alive(proc: psutil.Process) -> bool:
    try:
        return proc.is_running() and proc.status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


@pytest.fixture(autouse=True)
def no_process_left_behind(request):
    """Fail the test that leaves any process of the run alive (and kill what it left)."""
    yield
    left = run_processes()
    if left:
        _, left = psutil.wait_procs(left, timeout=5)
    if left:
        names = [f"{p.pid} {' '.join(p.cmdline()[:6])}" for p in left if _alive(p)]
        for proc in left:
            try:
                proc.kill()
            except psutil.Error:
                pass
        if names:
            pytest.fail(f"{request.node.nodeid} left processes behind: {names}")


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
