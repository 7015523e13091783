"""Does a swarm world hit MuJoCo 4.0.0's sparse-factor bug? Dense against sparse Jacobian.

    python -m bench.sparse_jacobian [--robots 16 64] [--steps 1500] [--pile] [--no-islands]
                                    [--elliptic] [--threads N] [--timing]

MuJoCo 4.0.1 fixes a Newton-solver bug that gave a wrong Hessian factor when the
constraint Jacobian is sparse (google-deepmind/mujoco #3767); MuJoCo picks the sparse
Jacobian itself (``jacobian="auto"``) from 60 degrees of freedom, which a swarm world of
six or more robots has. For each robot count: the bench swarm world (``bench.swarm``'s
arena and robots, compiled by ``descriptions.swarm_world`` as the physics node does), the
robots turned to face the centre (odd ones) or the nearest wall (even ones; ``--pile``: all
to the centre) and driven at full wheel speed, so that they push into each other and the
walls. Reported:

- one step from the same state (every 10th state of the dense run): the largest
  difference of ``qacc`` between the dense and the sparse Jacobian, relative to the largest
  acceleration; beside it how far each is from a reference solved to ``tolerance`` 1e-15
  (what the solver's own tolerance allows). A wrong Hessian factor would show here: the
  sparse answer would be further from the reference than the dense one.
- the whole trajectories: the largest ``qpos`` difference between dense and sparse (and
  auto) over time, against the same for the dense run and a dense run whose robots each
  started 1e-12 m off (how far contact amplifies a rounding difference: the chaos floor).
- ``--timing``: step time with each Jacobian, run alternately (meaningful only on an idle
  machine).
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

DENSE, SPARSE, AUTO = (mujoco.mjtJacobian.mjJAC_DENSE, mujoco.mjtJacobian.mjJAC_SPARSE,
                       mujoco.mjtJacobian.mjJAC_AUTO)
WHEEL_SPEED = 12.0  # rad/s: 0.72 m/s with the 0.06 m wheels, as fast as the motors go


@dataclass
class Swarm:
    """A compiled swarm world and its robots' names."""

    model: mujoco.MjModel
    robots: list[str]


def swarm(n: int, directory: Path | None = None) -> Swarm:
    """The bench swarm world of ``n`` robots (``bench.swarm.scenario``), compiled as the
    physics node compiles it, with MuJoCo's own Jacobian choice (auto)."""
    import nodes  # noqa: F401 - provides the node kinds to the plan
    from bench.swarm import scenario
    from descriptions.load import load_scenario
    from nodes.physics.world import load_model

    directory = directory or Path(tempfile.mkdtemp(prefix="sparse_jacobian_"))
    loaded = load_scenario(scenario(n, 5.0, directory))
    model = load_model(loaded.world, loaded.robots)
    return Swarm(model, loaded.robots.names)


def with_jacobian(model: mujoco.MjModel, jacobian: int) -> mujoco.MjModel:
    """A copy of ``model`` with its ``opt.jacobian`` set."""
    out = model.__copy__()
    out.opt.jacobian = jacobian
    return out


def start(world: Swarm, model: mujoco.MjModel, pile: bool = False,
          nudge: float = 0.0, threads: int = 1) -> mujoco.MjData:
    """The robots turned to the centre (odd) or away from it (even; ``pile``: all to the
    centre), wheels commanded forward, the odd ones turning a little; ``nudge`` moves every
    robot along x by that much, alternately + and - (m); ``threads`` > 1: the engine's pool."""
    data = _data(model, threads)
    for i, name in enumerate(world.robots):
        adr = model.jnt_qposadr[model.joint(f"{name}/base_free").id]
        x, y = data.qpos[adr], data.qpos[adr + 1]
        yaw = math.atan2(-y, -x) if pile or i % 2 else math.atan2(y, x)
        data.qpos[adr + 3:adr + 7] = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
        data.qpos[adr] += nudge * (-1) ** i
        left = model.actuator(f"{name}/left_wheel_motor").id
        right = model.actuator(f"{name}/right_wheel_motor").id
        data.ctrl[left] = WHEEL_SPEED
        data.ctrl[right] = WHEEL_SPEED * (0.75 if i % 2 else 1.0)
    mujoco.mj_forward(model, data)
    return data


def trajectory(world: Swarm, jacobian: int, steps: int, pile: bool = False,
               nudge: float = 0.0, threads: int = 1) -> np.ndarray:
    """qpos after each of ``steps`` steps."""
    model = with_jacobian(world.model, jacobian)
    data = start(world, model, pile, nudge, threads)
    out = np.empty((steps, model.nq))
    for k in range(steps):
        mujoco.mj_step(model, data)
        out[k] = data.qpos
    return out


def _data(model: mujoco.MjModel, threads: int) -> mujoco.MjData:
    data = mujoco.MjData(model)
    if threads > 1:
        mujoco.mju_threadpool(data, threads)
    return data


def _qacc_from(model: mujoco.MjModel, state: mujoco.MjData, threads: int = 1) -> np.ndarray:
    data = _data(model, threads)
    data.qpos[:], data.qvel[:], data.ctrl[:] = state.qpos, state.qvel, state.ctrl
    data.qacc_warmstart[:] = state.qacc_warmstart
    mujoco.mj_forward(model, data)
    return data.qacc.copy()


def one_step_errors(world: Swarm, steps: int, pile: bool = False, every: int = 10,
                    threads: int = 1) -> dict[str, float]:
    """From every ``every``-th state of the dense run: the largest relative difference of
    qacc dense against sparse, and each against a tightly solved reference."""
    dense, sparse = with_jacobian(world.model, DENSE), with_jacobian(world.model, SPARSE)
    reference = with_jacobian(world.model, DENSE)
    reference.opt.tolerance, reference.opt.iterations = 1e-15, 2000
    data = start(world, dense, pile, threads=threads)
    worst = {"dense_vs_sparse": 0.0, "dense_vs_reference": 0.0, "sparse_vs_reference": 0.0}
    touching = {"robot_robot": 0, "robot_wall": 0}
    for k in range(steps):
        if k % every == 0:
            qd, qs, qr = (_qacc_from(m, data, threads) for m in (dense, sparse, reference))
            scale = max(1.0, float(np.abs(qr).max()))
            for key, a, b in (("dense_vs_sparse", qd, qs), ("dense_vs_reference", qd, qr),
                              ("sparse_vs_reference", qs, qr)):
                worst[key] = max(worst[key], float(np.abs(a - b).max()) / scale)
            for key, count in contacts(dense, data).items():
                touching[key] = max(touching[key], count)
        mujoco.mj_step(dense, data)
    worst.update({f"{key}_contacts_max": count for key, count in touching.items()})
    return worst


def contacts(model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, int]:
    """How many contacts are between two robots, and between a robot and a wall."""
    out = {"robot_robot": 0, "robot_wall": 0}
    for i in range(data.ncon):
        geoms = data.contact[i].geom
        owners = [model.body(model.geom_bodyid[g]).name.partition("/") for g in geoms]
        robots = [head for head, slash, _ in owners if slash]
        if len(robots) == 2 and robots[0] != robots[1]:
            out["robot_robot"] += 1
        elif len(robots) == 1 and any(model.geom(g).name.startswith("wall") for g in geoms):
            out["robot_wall"] += 1
    return out


def divergence(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The largest |qpos| difference at each step."""
    return np.abs(a - b).max(axis=1)


def step_time(world: Swarm, steps: int, rounds: int = 5) -> dict[str, float]:
    """Microseconds a step with the dense and the sparse Jacobian, run alternately
    (best of ``rounds``), on the same contact-rich motion."""
    best = {"dense": math.inf, "sparse": math.inf}
    for _ in range(rounds):
        for name, jacobian in (("dense", DENSE), ("sparse", SPARSE)):
            model = with_jacobian(world.model, jacobian)
            data = start(world, model)
            began = time.perf_counter()
            for _ in range(steps):
                mujoco.mj_step(model, data)
            best[name] = min(best[name], (time.perf_counter() - began) / steps * 1e6)
    return best


def main(argv: list[str] | None = None) -> list[dict]:
    """Measure each robot count; print one block each."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, nargs="+", default=[16, 64])
    parser.add_argument("--steps", type=int, default=1500)
    parser.add_argument("--pile", action="store_true", help="every robot drives to the centre")
    parser.add_argument("--timing", action="store_true", help="also time a step of each")
    parser.add_argument("--no-islands", action="store_true",
                        help="one constraint problem for the whole world (mjDSBL_ISLAND)")
    parser.add_argument("--elliptic", action="store_true", help="elliptic friction cones")
    parser.add_argument("--threads", type=int, default=1,
                        help="the engine's thread pool (mju_threadpool), as params.threads")
    args = parser.parse_args(argv)
    print(f"mujoco {mujoco.__version__}")
    rows = []
    for n in args.robots:
        world = swarm(n)
        if args.no_islands:
            world.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ISLAND
        if args.elliptic:
            world.model.opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        auto_sparse = bool(mujoco.mj_isSparse(world.model))
        errors = one_step_errors(world, args.steps, args.pile, threads=args.threads)
        runs = {name: trajectory(world, jac, args.steps, args.pile, threads=args.threads)
                for name, jac in (("dense", DENSE), ("sparse", SPARSE), ("auto", AUTO))}
        nudged = trajectory(world, DENSE, args.steps, args.pile, 1e-12, args.threads)
        checkpoints = [c for c in (100, 300, 1000, args.steps) if c <= args.steps]
        row = {"robots": n, "nv": world.model.nv, "auto_is_sparse": auto_sparse, **errors}
        for label, other, base in (("sparse", runs["sparse"], runs["dense"]),
                                   ("auto", runs["auto"], runs["dense"]),
                                   ("nudged_1e-12", nudged, runs["dense"])):
            gap = divergence(base, other)
            row[f"qpos_gap_{label}"] = {c: float(gap[c - 1]) for c in checkpoints}
        if args.timing:
            row["step_us"] = step_time(world, min(args.steps, 1000))
        rows.append(row)
        print(_block(row))
    return rows


def _block(row: dict) -> str:
    lines = [f"{row['robots']} robots (nv {row['nv']}, auto picks "
             f"{'sparse' if row['auto_is_sparse'] else 'dense'}; at most "
             f"{row['robot_robot_contacts_max']} robot-robot and "
             f"{row['robot_wall_contacts_max']} robot-wall contacts at once)",
             f"  one step, relative qacc: dense vs sparse {row['dense_vs_sparse']:.1e}; "
             f"vs a reference solved to 1e-15: dense {row['dense_vs_reference']:.1e}, "
             f"sparse {row['sparse_vs_reference']:.1e}"]
    for key in ("sparse", "auto", "nudged_1e-12"):
        gaps = ", ".join(f"{c}: {v:.1e}" for c, v in row[f"qpos_gap_{key}"].items())
        lines.append(f"  max |qpos| gap, dense vs {key}, after step {gaps} m")
    if "step_us" in row:
        t = row["step_us"]
        lines.append(f"  step: dense {t['dense']:.0f} us, sparse {t['sparse']:.0f} us "
                     f"(dense/sparse {t['dense'] / t['sparse']:.2f})")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
