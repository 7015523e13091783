"""ros2_control's controller manager in the arm's lockstep: arm_control.yaml (the controller
manager at 100 Hz with its joint state broadcaster, the trajectory controller loaded and the
forward position controller taking the seeds' /joint_commands) over arm.yaml with physics at
the same 100 Hz and /joint_commands straight into physics, side by side in one invocation,
multi-process and in-process, the same simulated time (no stop at the goal).

    python -m bench.ros2_control [--repeats 3] [--seconds 3]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

import yaml

from bench.common import ROOT, run_manifest, write_scenario


def scenarios(seconds: int, directory: Path, node_process: str | None = None
              ) -> dict[str, Path]:
    """Both arms for ``seconds`` of simulated time, physics at 100 Hz, no stop at the goal."""
    out = {}
    for name in ("arm", "arm_control"):
        doc = yaml.safe_load((ROOT / "scenarios" / f"{name}.yaml").read_text())
        doc["name"] = f"bench_{name}"
        doc["world"] = str((ROOT / "scenarios" / doc["world"]).resolve())
        doc["duration"] = f"{seconds}s"
        doc["success"]["stop_on_goal"] = False
        doc.pop("interactive", None)
        for node in doc["nodes"]:
            if node["kind"] == "physics":
                node["rate"] = 100
                if node_process:
                    node["process"] = node_process
            if node["kind"] == "ros2_control":
                node["process"] = node_process
                node["params"]["controllers"] = str(
                    (ROOT / "scenarios" / node["params"]["controllers"]).resolve())
        directory.mkdir(parents=True, exist_ok=True)
        out[name] = write_scenario(doc, directory)
    return out


def main(argv: list[str] | None = None) -> None:
    """Print the loop of each (median), the ratios, and whether each scenario gave one
    digest; multi-process with the controller manager in its own process and in physics'
    (``process:``, as ros2_control's hardware interface shares the manager's process)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=int, default=3)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="cosim-bench-ros2-control-") as tmp:
        apart = scenarios(args.seconds, Path(tmp) / "apart")
        packed = scenarios(args.seconds, Path(tmp) / "packed", node_process="hardware")
        cases = {"arm": (apart["arm"], ()), "manager": (apart["arm_control"], ()),
                 "manager with physics": (packed["arm_control"], ()),
                 "arm in-process": (apart["arm"], ("--in-process",)),
                 "manager in-process": (apart["arm_control"], ("--in-process",))}
        loops: dict[str, list[float]] = {name: [] for name in cases}
        digests: dict[str, set[str]] = {name: set() for name in cases}
        for _ in range(args.repeats):
            for name, (path, extra) in cases.items():  # side by side: one of each per repeat
                manifest = run_manifest(path, *extra)
                loops[name].append(manifest["loop_s"])
                digests[name].add(manifest["digest"])
    m = {name: statistics.median(values) for name, values in loops.items()}
    print(f"{args.seconds} s simulated at 100 Hz, median of {args.repeats}: arm {m['arm']:.2f} s; "
          f"with the controller manager {m['manager']:.2f} s = {m['manager'] / m['arm']:.2f}x, "
          f"in physics' process {m['manager with physics']:.2f} s = "
          f"{m['manager with physics'] / m['arm']:.2f}x; in-process "
          f"{m['manager in-process'] / m['arm in-process']:.2f}x; one digest per case: "
          f"{all(len(d) == 1 for d in digests.values())}")


if __name__ == "__main__":
    main()
