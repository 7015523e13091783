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


def scenarios(seconds: int, directory: Path) -> dict[str, Path]:
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
            if node["kind"] == "ros2_control":
                node["params"]["controllers"] = str(
                    (ROOT / "scenarios" / node["params"]["controllers"]).resolve())
        out[name] = write_scenario(doc, directory)
    return out


def main(argv: list[str] | None = None) -> None:
    """Print the wall time of each, the ratio and whether each pair's digests agree."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=int, default=3)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="cosim-bench-ros2-control-") as tmp:
        paths = scenarios(args.seconds, Path(tmp))
        for mode, extra in (("multi-process", ()), ("in-process", ("--in-process",))):
            walls: dict[str, list[float]] = {name: [] for name in paths}
            digests: dict[str, set[str]] = {name: set() for name in paths}
            for _ in range(args.repeats):
                for name, path in paths.items():  # side by side: one of each per repeat
                    manifest = run_manifest(path, *extra)
                    walls[name].append(manifest["loop_s"])
                    digests[name].add(manifest["digest"])
            plain, managed = (statistics.median(walls[n]) for n in ("arm", "arm_control"))
            print(f"{mode}: arm_control loop {managed:.2f} s over arm {plain:.2f} s = "
                  f"{managed / plain:.2f}x (median of {args.repeats}, {args.seconds} s "
                  f"simulated at 100 Hz); digests one per scenario: "
                  f"{all(len(d) == 1 for d in digests.values())}")


if __name__ == "__main__":
    main()
