"""nav with its built-in controller, against the same controller as a plain rclpy program
(examples/control_as_ros_node.py) fed as a gated foreign program; both multi-process, run
interleaved in one invocation. Target (issue 17): foreign wall at most 1.5x built-in.
``--timer`` runs the program in its timer-driven shape (callbacks store, a 10 Hz sim-time
timer steps and publishes; it publishes nothing at tick 0, so its path differs slightly).

    .venv/bin/python -m bench.foreign_nav [--repeats 3] [--timer]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

import yaml

from bench.common import ROOT, run_manifest, write_scenario

NAV = ROOT / "scenarios" / "nav.yaml"
CONTROLLER = ROOT / "examples" / "control_as_ros_node.py"


def scenarios(tmp: Path, timer: bool = False) -> tuple[Path, Path]:
    """nav.yaml as it is, and with control replaced by the rclpy program (timer-driven
    with ``timer``)."""
    doc = yaml.safe_load(NAV.read_text())
    doc["world"] = str((NAV.parent / doc["world"]).resolve())
    doc["name"] = "nav_builtin"
    builtin = write_scenario(doc, tmp)
    control = next(n for n in doc["nodes"] if n["name"] == "control")
    control.pop("kind")
    control["command"] = ["python", str(CONTROLLER), "--ros-args", "-p", f"scenario:={builtin}"]
    if timer:
        control["command"] += ["-p", "timer_hz:=10.0"]
    control["params"] = {"outputs": {"/cmd_vel": "geometry_msgs/msg/Twist",
                                     "/plan": "nav_msgs/msg/Path"}}
    doc["name"] = "nav_foreign_control"
    return builtin, write_scenario(doc, tmp)


def main(argv: list[str] | None = None) -> float:
    """Print wall times and the ratio; return the median ratio."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--timer", action="store_true", help="the timer-driven controller")
    args = p.parse_args(argv)
    ratios = []
    with tempfile.TemporaryDirectory(prefix="cosim-bench-") as tmp:
        builtin, foreign = scenarios(Path(tmp), args.timer)
        for _ in range(args.repeats):
            ours = run_manifest(builtin)
            theirs = run_manifest(foreign)
            ratio = theirs["wall_time_s"] / ours["wall_time_s"]
            ratios.append(ratio)
            print(f"  nav built-in control {ours['wall_time_s']:6.2f} s wall "
                  f"({ours['outcome']['status']}, {ours['ticks']} ticks), as a foreign rclpy "
                  f"program {theirs['wall_time_s']:6.2f} s ({theirs['outcome']['status']}, "
                  f"{theirs['ticks']} ticks): {ratio:.2f}x")
            if theirs["outcome"]["status"] != ours["outcome"]["status"]:
                print(f"  warning: outcomes differ (built-in: {ours['outcome'].get('error')}; "
                      f"foreign: {theirs['outcome'].get('error')})")
    median = statistics.median(ratios)
    shape = "timer-driven " if args.timer else ""
    print(f"nav {shape}foreign control / built-in wall, median of {args.repeats}: {median:.2f}x "
          f"(target <= 1.5x)")
    return median


if __name__ == "__main__":
    main()
