"""ros2_control's controller manager in lockstep, run in the physics step (issue 48): what it
costs against the same robots commanded without it, side by side in one invocation, the
same simulated time (no stop at the goal), multi-process and in-process.

- **arm**: arm_control.yaml (the manager at 100 Hz with its joint state broadcaster, the
  trajectory controller loaded and the forward position controller taking the seeds'
  /joint_commands) over arm.yaml with physics at the same 100 Hz and /joint_commands
  straight into physics. Target (issue 48): at most 1.2x multi-process, 1.1x in-process.
- **swarm**: swarm_urdf_control.yaml with ``--robots`` robots (16), each with its own
  manager and diff drive controller taking the built-in controller's TwistStamped, against
  the same swarm whose controllers publish /cmd_vel straight into physics. Target: at most
  1.3x.

    python -m bench.ros2_control [--repeats 3] [--seconds 3] [--robots 16]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

import yaml

from bench.common import ROOT, run_manifest, write_scenario

SCENARIOS = ROOT / "scenarios"


def _absolute(doc: dict) -> dict:
    """The scenario's files named from anywhere (the world, the robots' description and
    packages, the controllers files)."""
    doc["world"] = str((SCENARIOS / doc["world"]).resolve())
    robots = doc.get("robots")
    if robots:
        robots["description"] = str((SCENARIOS / robots["description"]).resolve())
        packages = robots.get("urdf", {}).get("packages", {})
        for name, folder in packages.items():
            packages[name] = str((SCENARIOS / folder).resolve())
        if robots.get("controllers"):
            robots["controllers"] = str((SCENARIOS / robots["controllers"]).resolve())
    for node in doc["nodes"]:
        if node["kind"] == "ros2_control":
            node["params"]["controllers"] = str(
                (SCENARIOS / node["params"]["controllers"]).resolve())
    return doc


def _common(doc: dict, name: str, seconds: int) -> dict:
    doc["name"] = name
    doc["duration"] = f"{seconds}s"
    doc["success"]["stop_on_goal"] = False
    doc.pop("interactive", None)
    return _absolute(doc)


def arm_scenarios(seconds: int, directory: Path) -> dict[str, Path]:
    """Both arms for ``seconds`` of simulated time, physics at 100 Hz."""
    out = {}
    for name in ("arm", "arm_control"):
        doc = _common(yaml.safe_load((SCENARIOS / f"{name}.yaml").read_text()),
                      f"bench_{name}", seconds)
        for node in doc["nodes"]:
            if node["kind"] == "physics":
                node["rate"] = 100
        out[name] = write_scenario(doc, directory)
    return out


def swarm_scenarios(seconds: int, robots: int, directory: Path) -> dict[str, Path]:
    """swarm_urdf_control with ``robots`` robots: each robot's diff drive controller, and
    the same swarm with its controllers' /cmd_vel straight into physics."""
    base = yaml.safe_load((SCENARIOS / "swarm_urdf_control.yaml").read_text())
    side = max(3, round(1.6 * robots ** 0.5))  # room for the robots, 1.6 m apart or so
    base["robots"].update(count=robots, region={"x": [-side, side], "y": [-side, side]})
    managed = _common(yaml.safe_load(yaml.safe_dump(base)), "bench_swarm_control", seconds)
    plain = _common(yaml.safe_load(yaml.safe_dump(base)), "bench_swarm_cmd_vel", seconds)
    plain["robots"].pop("controllers")
    for node in plain["nodes"]:
        if node["kind"] == "physics":  # the built-in controller's TwistStamped, as the
            node["inputs"] = [{"topic": "/cmd_vel", "mode": "delayed"}]  # controllers take it
            node["params"]["enable_stamped_cmd_vel"] = True
        if node["kind"] == "control":
            node.pop("remap", None)
    return {"swarm": write_scenario(plain, directory),
            "swarm_control": write_scenario(managed, directory)}


def main(argv: list[str] | None = None) -> None:
    """Print each case's loop (median) and the ratios, and whether each case gave one
    digest over its repeats."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=int, default=3)
    parser.add_argument("--robots", type=int, default=16)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="cosim-bench-ros2-control-") as tmp:
        folder = Path(tmp)
        arm = arm_scenarios(args.seconds, folder)
        swarm = swarm_scenarios(args.seconds, args.robots, folder)
        cases = {"arm": (arm["arm"], ()), "manager": (arm["arm_control"], ()),
                 "arm in-process": (arm["arm"], ("--in-process",)),
                 "manager in-process": (arm["arm_control"], ("--in-process",)),
                 "swarm": (swarm["swarm"], ()), "swarm managers": (swarm["swarm_control"], ()),
                 "swarm in-process": (swarm["swarm"], ("--in-process",)),
                 "swarm managers in-process": (swarm["swarm_control"], ("--in-process",))}
        loops: dict[str, list[float]] = {name: [] for name in cases}
        digests: dict[str, set[str]] = {name: set() for name in cases}
        for _ in range(args.repeats):
            for name, (path, extra) in cases.items():  # side by side: one of each per repeat
                manifest = run_manifest(path, *extra)
                loops[name].append(manifest["loop_s"])
                digests[name].add(manifest["digest"])
    m = {name: statistics.median(values) for name, values in loops.items()}

    def ratio(case: str, base: str) -> str:
        return f"{m[case]:.3f} s / {m[base]:.3f} s = {m[case] / m[base]:.3f}x"

    print(f"{args.seconds} s simulated, median of {args.repeats}:")
    print(f"  arm, manager at 100 Hz vs /joint_commands: multi-process "
          f"{ratio('manager', 'arm')} (target 1.2x); in-process "
          f"{ratio('manager in-process', 'arm in-process')} (target 1.1x)")
    print(f"  {args.robots}-robot swarm, a diff drive controller each vs /cmd_vel: "
          f"multi-process {ratio('swarm managers', 'swarm')} (target 1.3x); in-process "
          f"{ratio('swarm managers in-process', 'swarm in-process')}")
    print(f"  one digest per case: {all(len(d) == 1 for d in digests.values())}")


if __name__ == "__main__":
    main()
