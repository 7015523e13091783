"""Wall time of MuJoCo's step of a swarm world against the size of the engine's thread pool,
and whether the state is bit-identical at every pool size.

    python -m bench.physics_threads --robots 16 64 256 1000 --save DIR     # writes DIR/*.mjb
    python bench/physics_threads.py DIR/*.mjb --threads 1 2 4 8 16 [--seconds 1]

The first form builds bench.swarm's arena with N robots (as the physics node compiles it)
and saves the compiled model; the second needs only ``mujoco`` and ``numpy`` (so it runs on
a machine without cosim installed). Each robot's wheels get a fixed, different speed so the
robots drive, turn and run into each other and the walls. For each pool size a fresh
``MjData`` steps ``--seconds`` of simulated time (``mju_threadpool(d, n)``; 1 means no pool);
the figure is wall seconds per simulated second, the least of ``--repeat`` runs, and the
final ``qpos``/``qvel`` are compared bit for bit against the run without a pool.
"""

from __future__ import annotations

import argparse
import hashlib
import time
from pathlib import Path

import mujoco
import numpy as np


def wheel_speeds(model: mujoco.MjModel) -> np.ndarray:
    """A fixed control per actuator: each robot's wheels (actuators named ``*left_wheel*`` and
    ``*right_wheel*``) drive it forwards at one of seven speeds, turning by one of five
    differences, so that robots cross each other's paths; every other actuator holds 0."""
    ctrl = np.zeros(model.nu)
    robot = 0
    for i in range(model.nu):
        name = model.actuator(i).name
        forward, turn = 4.0 + 0.5 * (robot % 7), 1.5 * ((robot % 5) - 2)
        if "left_wheel" in name:
            ctrl[i] = forward - turn
        elif "right_wheel" in name:
            ctrl[i] = forward + turn
            robot += 1
    return ctrl


def run(model: mujoco.MjModel, threads: int, steps: int) -> tuple[float, str, int]:
    """Wall seconds for ``steps`` steps with a pool of ``threads``, the state's hash and the
    contacts at the end."""
    data = mujoco.MjData(model)
    if threads > 1:
        mujoco.mju_threadpool(data, threads)
    data.ctrl[:] = wheel_speeds(model)
    start = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data)
    wall = time.perf_counter() - start
    digest = hashlib.sha256(data.qpos.tobytes() + data.qvel.tobytes()).hexdigest()[:16]
    return wall, digest, int(data.ncon)


def measure(path: Path, threads: list[int], seconds: float, repeat: int) -> None:
    """Print one line per pool size for the saved model at ``path``."""
    model = mujoco.MjModel.from_binary_path(str(path))
    steps = round(seconds / model.opt.timestep)
    reference = None
    for n in threads:
        best, digest, ncon = min(run(model, n, steps) for _ in range(repeat))
        reference = reference or digest
        same = "same state" if digest == reference else f"STATE DIFFERS ({digest})"
        print(f"{path.stem}: {n:>2} threads {best / seconds:8.3f} wall s per sim s "
              f"({ncon} contacts at the end) {same}", flush=True)


def save(robots: list[int], directory: Path) -> None:
    """Compile bench.swarm's world for each robot count (as the physics node does) into
    ``directory/swarmN.mjb``."""
    from bench.swarm import scenario
    from descriptions.load import load_scenario
    from orchestrator.lockstep.inprocess import make_node

    directory.mkdir(parents=True, exist_ok=True)
    for n in robots:
        node = make_node(load_scenario(scenario(n, 1.0, directory)), "physics")
        out = directory / f"swarm{n}.mjb"
        mujoco.mj_saveModel(node.model, str(out), None)
        print(f"{out}: {node.model.nbody} bodies, {node.model.nu} actuators, "
              f"timestep {node.model.opt.timestep}", flush=True)


def main(argv: list[str] | None = None) -> None:
    """Save models (``--save``) or measure saved ones."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("models", nargs="*", type=Path, help="saved .mjb models to measure")
    parser.add_argument("--robots", type=int, nargs="+", default=[16, 64, 256, 1000])
    parser.add_argument("--save", type=Path, help="compile and save the models here")
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    parser.add_argument("--seconds", type=float, default=1.0)
    parser.add_argument("--repeat", type=int, default=2)
    a = parser.parse_args(argv)
    if a.save:
        save(a.robots, a.save)
    for path in a.models:
        measure(path, a.threads, a.seconds, a.repeat)


if __name__ == "__main__":
    main()
