"""Swarm worlds against MuJoCo 4.0.0's sparse-factor bug (issue 50, item 7).

MuJoCo 4.0.1 fixes a wrong Hessian factor in the Newton solver when the constraint Jacobian
is sparse (google-deepmind/mujoco #3767); MuJoCo picks the sparse Jacobian by itself for a
swarm world. Measured (bench/README.md, ``python -m bench.sparse_jacobian``): cosim's swarm
worlds do not hit it, so their Jacobian is left to MuJoCo and no version is pinned. This
test is the guard instead: on whatever MuJoCo is installed, from the same states with robots
pushing each other and the walls, the sparse Jacobian's accelerations equal the dense one's
to rounding; a wrong factor on the path swarm worlds take fails it.
"""

from __future__ import annotations

import mujoco

from bench.sparse_jacobian import one_step_errors, swarm

ROUNDING = 1e-9  # relative: measured 1.2e-13 on 4.0.0; the solver's own tolerance is 1e-8


def test_swarm_world_in_contact_gets_the_same_answer_from_the_sparse_jacobian(tmp_path):
    world = swarm(16, tmp_path)
    assert mujoco.mj_isSparse(world.model), "auto no longer picks sparse: see bench/README.md"
    errors = one_step_errors(world, steps=800, every=20)
    assert errors["robot_robot_contacts_max"] > 0 and errors["robot_wall_contacts_max"] > 0
    assert errors["dense_vs_sparse"] < ROUNDING, (
        f"mujoco {mujoco.__version__}: a swarm world's sparse-Jacobian step differs from the "
        f"dense one by {errors['dense_vs_sparse']:.1e} (relative qacc): pin "
        "model.opt.jacobian to mjJAC_DENSE in descriptions/swarm_world.py (bench/README.md)")
