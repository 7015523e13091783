"""nav with its built-in controller, against the same controller as a plain rclpy program
(examples/control_as_ros_node.py) fed as a gated foreign program, through the Python gate and
through the RMW gate (librmw_cosim_gate.so); all multi-process, run interleaved in one
invocation. Target (issues 17, 30): foreign wall at most 1.5x built-in, through each gate.
``--timer`` runs the program in its timer-driven shape (callbacks store, a 10 Hz sim-time
timer steps and publishes; it publishes nothing at tick 0, so its path differs slightly).

    .venv/bin/python -m bench.foreign_nav [--repeats 3] [--gates python,rmw] [--timer]
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


def scenarios(tmp: Path, gate: str = "python", timer: bool = False) -> tuple[Path, Path]:
    """nav.yaml as it is, and with control replaced by the rclpy program behind ``gate``
    (timer-driven with ``timer``)."""
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
                                     "/plan": "nav_msgs/msg/Path"}, "gate": gate}
    doc["name"] = f"nav_foreign_control_{gate}"
    return builtin, write_scenario(doc, tmp)


def main(argv: list[str] | None = None) -> dict[str, float]:
    """Print wall times and the ratios; return the median ratio of each gate."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--gates", default="python,rmw", help="comma-separated: python, rmw")
    p.add_argument("--timer", action="store_true", help="the timer-driven controller")
    args = p.parse_args(argv)
    gates = [g for g in args.gates.split(",") if g]
    ratios: dict[str, list[float]] = {g: [] for g in gates}
    with tempfile.TemporaryDirectory(prefix="cosim-bench-") as tmp:
        foreign = {}
        for gate in gates:
            folder = Path(tmp) / gate
            folder.mkdir()
            builtin, foreign[gate] = scenarios(folder, gate, args.timer)
        for _ in range(args.repeats):
            ours = run_manifest(builtin)
            line = (f"  nav built-in control {ours['wall_time_s']:6.2f} s wall "
                    f"({ours['outcome']['status']}, {ours['ticks']} ticks)")
            for gate in gates:
                theirs = run_manifest(foreign[gate])
                ratio = theirs["wall_time_s"] / ours["wall_time_s"]
                ratios[gate].append(ratio)
                line += (f"; rclpy program, {gate} gate {theirs['wall_time_s']:6.2f} s "
                         f"({theirs['outcome']['status']}, {theirs['ticks']} ticks): "
                         f"{ratio:.2f}x")
                if theirs["outcome"]["status"] != ours["outcome"]["status"]:
                    line += (f" [outcomes differ: built-in {ours['outcome'].get('error')}; "
                             f"{gate} gate {theirs['outcome'].get('error')}]")
            print(line)
    medians = {g: statistics.median(r) for g, r in ratios.items()}
    shape = "timer-driven " if args.timer else ""
    for gate, median in medians.items():
        print(f"nav {shape}foreign control ({gate} gate) / built-in wall, median of "
              f"{args.repeats}: {median:.2f}x (target <= 1.5x)")
    return medians


if __name__ == "__main__":
    main()
