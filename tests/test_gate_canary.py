"""The foreign-program gate against the installed rclpy: every rclpy internal it depends on
still looks as it expects (a failure names the one that changed), and an executor it cannot
see is refused by name when the program makes one, not left to a start-deadline timeout."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from orchestrator.proxies.foreign_launch import GATE_DIR, GATE_ENV
from runtime.foreign_gate.canary import CHECKS
from runtime.foreign_gate.cosim_gate import EXIT_UNSUPPORTED


@pytest.mark.parametrize("name", list(CHECKS))
def test_the_rclpy_internal_the_gate_uses_is_unchanged(name):
    try:
        CHECKS[name]()
    except AssertionError as exc:
        pytest.fail(f"rclpy changed what the gate relies on: {name}: {exc}")


GATED = {"prefix": "/cosim/feed/ctl/", "node": "ctl", "tick_ns": 10_000_000, "period": 1,
         "start": 0, "inputs": [{"topic": "/cosim/feed/ctl/odom"}]}


def run_gated(code: str) -> subprocess.CompletedProcess:
    """Run ``code`` as a foreign program is run: the gate injected through sitecustomize."""
    env = {**os.environ, GATE_ENV: json.dumps(GATED),
           "PYTHONPATH": os.pathsep.join([str(GATE_DIR), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, timeout=120)


def test_an_events_executor_is_refused_by_name_at_start():
    run = run_gated("import rclpy\nfrom rclpy.experimental import EventsExecutor\n"
                    "rclpy.init()\nEventsExecutor()\nprint('made one')\n")
    assert run.returncode == EXIT_UNSUPPORTED, run.stderr
    assert "EventsExecutor" in run.stderr and "SingleThreadedExecutor" in run.stderr
    assert "made one" not in run.stdout


def test_an_executor_the_gate_sees_is_still_made():
    run = run_gated("import rclpy\nimport rclpy.experimental\nrclpy.init()\n"
                    "ex = rclpy.executors.SingleThreadedExecutor()\nex.shutdown()\n"
                    "rclpy.shutdown()\nprint('made one')\n")
    assert run.returncode == 0, run.stderr
    assert "made one" in run.stdout
