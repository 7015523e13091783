"""CPU of the physics node's step in a swarm, against MuJoCo's own mj_step for the same world.

    python -m bench.physics_step [--robots 16 64] [--ticks 100] [--repeat 3] [--imu]

For each robot count: bench.swarm's arena and robots, the physics node built as every
driver builds it, stepped in-process for ``--ticks`` activations with a constant /cmd_vel
per robot (each robot its own; ``--imu``: with the default IMU, which bench.swarm leaves
out), CPU time (``time.process_time``) per simulated second; then
the floor: the same number of bare ``mj_step`` calls on a copy of the node's world with the
same controls. Process CPU, not wall: it means something on a loaded machine too; each
figure is the least of ``--repeat`` fresh runs (other processes only ever add to it).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import mujoco
from geometry_msgs.msg import Twist

from bench.swarm import scenario
from descriptions.load import load_scenario
from nodes.contract import Tick, take_output_marks
from orchestrator.lockstep.inprocess import make_node


def commands(n: int) -> dict[str, Twist]:
    """One /cmd_vel per robot, different for each."""
    out = {}
    for i in range(n):
        msg = Twist()
        msg.linear.x = 0.2 + 0.01 * (i % 7)
        msg.angular.z = 0.3 * ((i % 5) - 2)
        out[f"/robot_{i}/cmd_vel"] = msg
    return out


def measure(n: int, ticks: int, directory: Path, imu: bool = False) -> dict[str, float]:
    """The node's step CPU and bare mj_step CPU, seconds per simulated second."""
    sc = load_scenario(scenario(n, 10.0, directory),
                       {"nodes.physics.params": {}} if imu else None)
    node = make_node(sc, "physics")
    period_ns = sc.nodes["physics"].spec.period_ns
    inputs = commands(n)
    node.step(Tick(0, 0), inputs)
    take_output_marks()  # as the runtime takes them after every step
    start = time.process_time()
    for k in range(1, ticks + 1):
        node.step(Tick(k, k * period_ns), inputs)
        take_output_marks()
    step_s = time.process_time() - start
    model, data = node.model, node.data
    substeps = node.substeps
    start = time.process_time()
    for _ in range(ticks * substeps):
        mujoco.mj_step(model, data)
    floor_s = time.process_time() - start
    sim_s = ticks * period_ns / 1e9
    return {"step": step_s / sim_s, "mj_step": floor_s / sim_s}


def main(argv: list[str] | None = None) -> None:
    """Print the node's step and MuJoCo's own, CPU s per simulated s, per robot count."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, nargs="+", default=[16, 64])
    parser.add_argument("--ticks", type=int, default=100)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--imu", action="store_true", help="the physics node's default IMU")
    a = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="cosim-physics-step-") as tmp:
        for n in a.robots:
            runs = [measure(n, a.ticks, Path(tmp), a.imu) for _ in range(a.repeat)]
            r = {key: min(run[key] for run in runs) for key in ("step", "mj_step")}
            r["ratio"] = r["step"] / r["mj_step"]
            print(f"{n:>5} robots: physics step {r['step']:.3f} CPU s per sim s, "
                  f"mj_step {r['mj_step']:.3f}, ratio {r['ratio']:.2f}", flush=True)


if __name__ == "__main__":
    main()
