"""cosim started from another Python that bootstrapped ROS 2 wheels of its own: the child
inherits that Python's LD_LIBRARY_PATH and the wheels' bootstrap flag, and must still load
its own libraries (runtime/ros_libraries.py)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from runtime.ros_libraries import BOOTSTRAP_FLAG, fixed_library_path, own_library_dirs
from tests.helpers import ROOT, orchestrate

NAV = ROOT / "scenarios" / "nav.yaml"
NEAR_GOAL = {"goal.x": -2.3, "goal.y": -2.3, "goal.yaw": 0.785, "duration": "8s"}
COSIM_BUILT = ("libtf2_msgs__", "libnav2_msgs__", "libsimulation_interfaces__")


def foreign_wheels(where: Path) -> Path:
    """A stand-in for another venv's ROS 2 wheels: every library of ours that the wheels
    ship, none of the interface packages cosim builds at install."""
    lib = where / "other_venv" / "lib"
    lib.mkdir(parents=True)
    for d in own_library_dirs():
        for so in Path(d).glob("*.so*"):
            if not so.name.startswith(COSIM_BUILT) and not (lib / so.name).exists():
                (lib / so.name).symlink_to(so)
    assert not list(lib.glob("libtf2_msgs__*"))
    return lib


def test_nav_runs_from_a_python_with_other_ros_wheels(tmp_path):
    foreign = foreign_wheels(tmp_path)
    env = {BOOTSTRAP_FLAG: "1", "LD_LIBRARY_PATH": f"{foreign}{os.pathsep}/stale/ros/lib"}
    sets = [a for k, v in NEAR_GOAL.items() if k != "duration" for a in ("--set", f"{k}={v}")]
    run = orchestrate(NAV, tmp_path / "runs", *sets, "--duration", NEAR_GOAL["duration"],
                      env=env)
    assert run.code == 0, run.stderr
    assert run.manifest["outcome"]["success"] is True
    reference = run_in_process(load_scenario(NAV, {k: v for k, v in NEAR_GOAL.items()}))
    assert run.manifest["digest"] == reference.digest


def test_library_path_puts_our_directories_first():
    own = [f"{sys.prefix}/lib", "/venv/ros_rcl.libs"]
    assert fixed_library_path({"LD_LIBRARY_PATH": os.pathsep.join(reversed(own))}, own) is None
    assert fixed_library_path({"LD_LIBRARY_PATH": os.pathsep.join([*own, "/x"])}, own) is None
    fixed = fixed_library_path({"LD_LIBRARY_PATH": f"/other/lib:{own[1]}:/other/lib"}, own)
    assert fixed.split(os.pathsep) == [*own, "/other/lib"]
    assert fixed_library_path({}, own).split(os.pathsep) == own
