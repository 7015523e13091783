"""Test-suite isolation: a ROS domain of its own per test run, and no process left behind
(found by ancestry and by the session's mark: tests/leftovers.py)."""

from __future__ import annotations

import gc
import os
import time

import psutil
import pytest

import nodes  # noqa: F401 - provides the node kinds to the plan (plan.kinds)
from tests.leftovers import alive, become_subreaper, mark_this_session, session_processes


def _test_domain() -> str:
    """COSIM_TEST_DOMAIN, else a domain id leased for as long as this process lives (a held
    lock, as a run's own: orchestrator.domains), so that test processes side by side (pytest-xdist
    workers, two checkouts' suites) and the runs they start unpinned never share one."""
    if os.environ.get("COSIM_TEST_DOMAIN"):
        return os.environ["COSIM_TEST_DOMAIN"]
    from orchestrator.domains import DomainLease

    lease = DomainLease(wait_s=60)
    domain = lease.__enter__()
    _HELD.append(lease)  # released when this process ends, however it ends
    return str(domain)


_HELD: list = []
# One domain per test process, chosen before anything imports rclpy; children inherit it.
DOMAIN = _test_domain()
os.environ["ROS_DOMAIN_ID"] = DOMAIN
# Discovery on this machine only, as cosim-orchestrate keeps a run's: a client on the default
# range (SUBNET) was not found by, nor found, a busy LOCALHOST run's services here
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("MUJOCO_GL", "egl")
mark_this_session()
become_subreaper()


@pytest.fixture(autouse=True)
def no_participant_left_behind(request):
    """Fail the test that leaves a DDS participant of this process on the test domain (an
    rclpy node not destroyed): half-built servers left so were found by the clients of later
    tests' runs, which then waited for answers that never came."""
    before = participant_ids()
    yield
    deadline = time.monotonic() + 5.0  # a participant goes when its last node is collected
    while (left := participant_ids() - before) and time.monotonic() < deadline:
        gc.collect()
        time.sleep(0.2)
    if left:
        pytest.fail(f"{request.node.nodeid} left {len(left)} DDS participant(s) of the test "
                    f"process on ROS domain {DOMAIN} (participant ids {sorted(left)}): an "
                    "rclpy node or context was not destroyed")


def participant_ids() -> set[int]:
    """The participant ids this process holds on the test domain (each participant binds
    its metatraffic unicast port 7410 + 250 * domain + 2 * id, RTPS 9.6.1.1)."""
    base = 7410 + 250 * int(DOMAIN)
    return {(c.laddr.port - base) // 2 for c in psutil.Process().net_connections(kind="udp")
            if base <= c.laddr.port < base + 250 and (c.laddr.port - base) % 2 == 0}


@pytest.fixture(autouse=True)
def no_process_left_behind(request):
    """Fail the test that leaves any process of the run alive (and kill what it left).
    What runs when it starts belongs to a fixture of a wider scope (a module's Ray cluster),
    which stops it itself."""
    before = {_identity(p) for p in session_processes()}
    yield
    names = _stop_leftovers([p for p in session_processes() if _identity(p) not in before])
    if names:
        pytest.fail(f"{request.node.nodeid} left processes behind: {names}")


def _stop_leftovers(left: list) -> list[str]:
    """Give ``left`` 5 s to end, kill what remains, and name what was still alive."""
    if left:
        _, left = psutil.wait_procs(left, timeout=5)
    names = [_describe(p) for p in left if alive(p)]
    for proc in left:
        try:
            proc.kill()
        except psutil.Error:
            pass
    return names


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Fail the session if anything outlived it (a wider fixture's processes included)."""
    names = _stop_leftovers(session_processes())
    if names:
        print(f"\nthe test session left processes behind: {names}")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def _identity(proc: psutil.Process) -> tuple[int, float]:
    """A process's pid and start time (a pid alone may be reused)."""
    try:
        return proc.pid, proc.create_time()
    except psutil.Error:
        return proc.pid, 0.0


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
    from runtime.transport.ros2 import destroy_node

    executor.shutdown()
    destroy_node(node)  # with the action clients a test made on it
    rclpy.shutdown(context=context)
