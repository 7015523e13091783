"""Pause, step, resume and reset a running lockstep run through real ROS 2 service calls."""

from __future__ import annotations

import subprocess
import time

from std_srvs.srv import SetBool, Trigger

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from tests.helpers import ORCHESTRATE, ROOT, SCENARIOS

PROTOCOL = SCENARIOS / "protocol.yaml"


def call(ros, srv_type, name: str, request):
    """Call a service from the test's plain rclpy node and wait for its answer."""
    node, executor = ros
    client = node.create_client(srv_type, name)
    assert client.wait_for_service(timeout_sec=30), f"{name} never appeared"
    future = client.call_async(request)
    executor.spin_until_future_complete(future, timeout_sec=30)
    assert future.done(), f"{name} did not answer"
    node.destroy_client(client)
    return future.result()


def wait_paused_at(ros, tick: int, timeout: float = 20.0) -> str:
    """Ask for the state (pausing again changes nothing) until it says 'paused at tick N'."""
    end = time.monotonic() + timeout
    while True:
        message = call(ros, SetBool, "/cosim/pause", SetBool.Request(data=True)).message
        if message.startswith(f"paused at tick {tick} ") or time.monotonic() > end:
            assert message.startswith(f"paused at tick {tick} "), message
            return message
        time.sleep(0.1)


def test_pause_step_reset_resume(tmp_path, ros_node):
    run = subprocess.Popen([*ORCHESTRATE, str(PROTOCOL), "--paused",
                            "--quiet", "--out", str(tmp_path)], cwd=ROOT,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        for _ in range(3):
            reply = call(ros_node, Trigger, "/cosim/step", Trigger.Request())
            assert reply.success, reply.message
        assert wait_paused_at(ros_node, 3)
        reply = call(ros_node, Trigger, "/cosim/reset", Trigger.Request())
        assert reply.success and "resetting to tick 0" in reply.message
        call(ros_node, Trigger, "/cosim/step", Trigger.Request())
        assert wait_paused_at(ros_node, 1)
        reply = call(ros_node, SetBool, "/cosim/pause", SetBool.Request(data=False))
        assert reply.success and reply.message.startswith("running")
        out, err = run.communicate(timeout=60)
    finally:
        if run.poll() is None:
            run.kill()
            run.communicate()
    assert run.returncode == 0, err
    fresh = run_in_process(load_scenario(PROTOCOL)).digest
    assert f"digest {fresh}" in out  # the run after the reset equals a fresh run


def test_step_while_running_is_refused(tmp_path, ros_node):
    long_run = SCENARIOS / "long_chain.yaml"
    run = subprocess.Popen([*ORCHESTRATE, str(long_run), "--quiet",
                            "--out", str(tmp_path)], cwd=ROOT, stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
    try:
        reply = call(ros_node, Trigger, "/cosim/step", Trigger.Request())
        assert not reply.success and reply.message.startswith("not paused")
        assert "running at tick" in reply.message
    finally:
        run.terminate()
        run.communicate(timeout=30)
    assert run.returncode == 130
