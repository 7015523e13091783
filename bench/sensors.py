"""Sensor cost: lidar beams 360 to 2048, camera sizes 160x120 to 640x480, RGB and depth.

    python -m bench.sensors

Each sensor configuration steps the real SensorsNode in-process on the nav world (the robot
at its start pose) and reports the mean step time, next to the physics step of the same
world measured in the same run (the ratio is what matters on another machine).
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported

import nodes  # noqa: E402, F401 - provides the node kinds to the plan (plan.kinds)
from bench.common import ROOT  # noqa: E402
from descriptions.load import load_scenario  # noqa: E402
from nodes.contract import Tick, take_output_marks  # noqa: E402
from orchestrator.lockstep.inprocess import make_node  # noqa: E402

NAV = ROOT / "scenarios" / "nav.yaml"


def mean_step_ms(scenario, name: str, inputs: dict, repeats: int) -> float:
    """Mean wall time of ``repeats`` steps of node ``name`` (after one warm-up step)."""
    node = make_node(scenario, name)
    node.step(Tick(0, 0), inputs)
    take_output_marks()  # as the runtime takes them after every step
    start = time.perf_counter()
    for k in range(1, repeats + 1):
        node.step(Tick(k, k * scenario.tick_ns), inputs)
        take_output_marks()
    return (time.perf_counter() - start) / repeats * 1e3


def world_state(scenario) -> dict:
    """The physics outputs at tick 0, to feed the sensors."""
    physics = make_node(scenario, "physics")
    return physics.step(Tick(0, 0), {})


def sensor_case(node: str, params: dict, repeats: int) -> float:
    """Mean step ms of the nav node ``node`` (lidar or camera) configured with ``params``."""
    scenario = load_scenario(NAV, {f"nodes.{node}.params": params})
    state = world_state(scenario)
    return mean_step_ms(scenario, node, {"/cosim/world_state": state["/cosim/world_state"]},
                        repeats)


def main() -> list[tuple[str, float]]:
    """Print the table; returns (case, ms) rows."""
    scenario = load_scenario(NAV)
    rows = [("physics step (10 substeps)", mean_step_ms(scenario, "physics", {}, 200))]
    for beams in (360, 720, 1024, 2048):
        lidar = {"lidar": {"beams": beams}}
        rows.append((f"lidar {beams} beams", sensor_case("lidar", lidar, 100)))
    for w, h in ((160, 120), (320, 240), (640, 480)):
        for depth in (False, True):
            cam = {"camera": {"width": w, "height": h, "depth": depth}}
            label = f"camera {w}x{h} RGB" + (" + depth" if depth else "")
            rows.append((label, sensor_case("camera", cam, 10)))
    physics = rows[0][1]
    for name, ms in rows:
        print(f"{name:36s} {ms:8.2f} ms   {ms / physics:6.2f} x physics step")
    return rows


if __name__ == "__main__":
    main()
