"""Your own robot: nav_urdf.yaml (mybot, a xacro URDF with package:// meshes, expanded and
converted at load) against the same scenario with cosim's MJCF robot (worlds/robot.xml) in
its place, and with mybot described in USD as Isaac Sim's importer writes it
(robots/usd/mybot_isaac.usda), side by side in one invocation: start-up (command to first
tick) and the tick loop's wall, multi-process, the same simulated time (no stop at the goal).

    python -m bench.urdf [--repeats 3] [--seconds 10]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

import yaml

from bench.common import ROOT, run_manifest, write_scenario

LIDAR = {"beams": 360, "range_max": 3.5, "range_min": 0.12, "noise_stddev": 0.01}


def scenarios(seconds: int, directory: Path) -> dict[str, Path]:
    """nav_urdf and its twin with the MJCF robot, ``seconds`` long, no stop at the goal."""
    doc = yaml.safe_load((ROOT / "scenarios" / "nav_urdf.yaml").read_text())
    doc["world"] = str((ROOT / "scenarios" / doc["world"]).resolve())
    doc["duration"] = f"{seconds}s"
    doc["success"]["stop_on_goal"] = False
    robots = doc["robots"]
    urdf = dict(doc, name="bench_urdf", robots=dict(robots))
    urdf["robots"]["description"] = str((ROOT / "scenarios" / robots["description"]).resolve())
    urdf["robots"]["urdf"] = dict(robots["urdf"], packages={
        k: str((ROOT / "scenarios" / v).resolve()) for k, v in robots["urdf"]["packages"].items()})
    mjcf = dict(doc, name="bench_mjcf", robots={k: v for k, v in robots.items() if k != "urdf"})
    mjcf["robots"]["description"] = str((ROOT / "scenarios" / "worlds" / "robot.xml").resolve())
    mjcf["nodes"] = []
    for node in doc["nodes"]:
        node = dict(node, params=dict(node.get("params") or {}))
        node["params"].pop("robot_description", None)
        if node["kind"] == "sensors":
            node["params"]["lidar"] = LIDAR  # what mybot's Gazebo tag gives its lidar
        mjcf["nodes"].append(node)
    usd_settings = yaml.safe_load(
        (ROOT / "scenarios" / "nav_usd_robot.yaml").read_text())["robots"]["usd"]
    usd = dict(doc, name="bench_usd", robots={k: v for k, v in robots.items() if k != "urdf"})
    usd["robots"]["description"] = str(
        (ROOT / "scenarios" / "robots" / "usd" / "mybot_isaac.usda").resolve())
    usd["robots"]["usd"] = usd_settings
    usd["nodes"] = [dict(n, params=dict(n.get("params") or {}, lidar=LIDAR))
                    if n["kind"] == "sensors" else n for n in doc["nodes"]]
    return {"urdf": write_scenario(urdf, directory), "mjcf": write_scenario(mjcf, directory),
            "usd": write_scenario(usd, directory)}


def main(argv: list[str] | None = None) -> None:
    """Print start-up and loop of each (median), the differences and ratios, and whether each
    scenario gave one digest."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=int, default=10)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="cosim-bench-urdf-") as tmp:
        paths = scenarios(args.seconds, Path(tmp))
        start: dict[str, list[float]] = {n: [] for n in paths}
        loop: dict[str, list[float]] = {n: [] for n in paths}
        digests: dict[str, set[str]] = {n: set() for n in paths}
        for _ in range(args.repeats):
            for name, path in paths.items():  # side by side: one of each per repeat
                manifest = run_manifest(path)
                start[name].append(manifest["startup"]["command_to_first_tick_s"])
                loop[name].append(manifest["loop_s"])
                digests[name].add(manifest["digest"])
    s_m, l_m = statistics.median(start["mjcf"]), statistics.median(loop["mjcf"])
    for name in ("urdf", "usd"):
        s, lp = statistics.median(start[name]), statistics.median(loop[name])
        print(f"start-up (command to first tick): {name.upper()} {s:.2f} s, MJCF {s_m:.2f} s, "
              f"{s - s_m:+.2f} s; tick loop: {name.upper()} {lp:.2f} s, MJCF {l_m:.2f} s = "
              f"{lp / l_m:.2f}x (median of {args.repeats}, {args.seconds} s simulated)")
    s_u, s_d = statistics.median(start["urdf"]), statistics.median(start["usd"])
    print(f"USD against URDF: start-up {s_d - s_u:+.2f} s, tick loop "
          f"{statistics.median(loop['usd']) / statistics.median(loop['urdf']):.2f}x; "
          f"one digest each: {all(len(d) == 1 for d in digests.values())}")


if __name__ == "__main__":
    main()
