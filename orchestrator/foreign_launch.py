"""The command line of a foreign program (kept apart from ``orchestrator.foreign_proxy``, which
loads rclpy: the orchestrator builds it before it forks its own node processes)."""

from __future__ import annotations

import sys
from pathlib import Path


def foreign_argv(plan, scenario_dir: Path) -> list[str]:
    """The program's command line: 'python' means this interpreter; use_sim_time and the
    scenario's remaps are appended as a ROS arguments block of their own."""
    argv = list(plan.spec.command)
    if argv[0] in ("python", "python3"):
        argv[0] = sys.executable
    argv += ["--ros-args", "-p", "use_sim_time:=true"]
    for own, graph in plan.spec.remap.items():
        argv += ["-r", f"{own}:={graph}"]
    return argv
