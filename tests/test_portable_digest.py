"""A digest does not depend on which CPU kernels the machine's libraries pick: nav without its
camera gives one digest whichever kernels OpenBLAS is told to use (OPENBLAS_CORETYPE) and with
numpy's CPU dispatch cut back to its baseline (NPY_DISABLE_CPU_FEATURES), in-process and
multi-process. Every run is a real cosim-orchestrate process, so the variables are read
where they take effect: at the start of the interpreters that load numpy and OpenBLAS."""

from __future__ import annotations

import yaml

from tests.helpers import nav_without_camera_doc, orchestrate

# numpy's dispatch targets above its x86-64 baseline; names it does not know are ignored
# with a warning on a machine without them, so this works on any x86-64.
NPY_BASELINE_ONLY = "X86_V3 X86_V4 AVX512_ICL AVX512_SPR"


def nav_without_camera(tmp_path, duration: str = "1s"):
    """nav minus its camera (rendered pixels depend on the renderer, not the CPU), short."""
    doc = nav_without_camera_doc(duration)
    path = tmp_path / "nav_nocam.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_one_digest_whatever_blas_kernels_and_numpy_cpu_features(tmp_path):
    scenario = nav_without_camera(tmp_path)
    runs = {
        "Haswell": ({"OPENBLAS_CORETYPE": "Haswell"}, ["--in-process"]),
        "SkylakeX": ({"OPENBLAS_CORETYPE": "SkylakeX"}, ["--in-process"]),
        "Sandybridge, numpy baseline": ({"OPENBLAS_CORETYPE": "Sandybridge",
                                         "NPY_DISABLE_CPU_FEATURES": NPY_BASELINE_ONLY},
                                        ["--in-process"]),
        "SkylakeX, multi-process": ({"OPENBLAS_CORETYPE": "SkylakeX"}, []),
    }
    digests = {}
    for label, (env, args) in runs.items():
        done = orchestrate(scenario, tmp_path / "runs", "--quiet", *args, env=env)
        assert done.code == 1, (label, done.stderr)  # 1 s is too short to reach the goal
        digests[label] = done.manifest["digest"]
    assert len(set(digests.values())) == 1, digests


def test_rot3_is_the_matrix_product_summed_in_one_fixed_order():
    """plan.rot3 gives numpy's products to rounding, and its own bits are the sum of the
    three products left to right, whatever the CPU (no BLAS, no fused multiply-add)."""
    import numpy as np

    from plan import rot3

    rng = np.random.default_rng(5)
    m, n = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    v, rows = rng.normal(size=3), rng.normal(size=(7, 3))
    np.testing.assert_allclose(rot3.mat_vec(m, v), m @ v, rtol=1e-13)
    np.testing.assert_allclose(rot3.mat_t_vec(m, v), m.T @ v, rtol=1e-13)
    np.testing.assert_allclose(rot3.mat_mul(m, n), m @ n, rtol=1e-13)
    np.testing.assert_allclose(rot3.mat_t_mul(m, n), m.T @ n, rtol=1e-13)
    np.testing.assert_allclose(rot3.rotate_rows(rows, m), rows @ m.T, rtol=1e-12)
    np.testing.assert_allclose(rot3.row_dots(rows, rows), (rows * rows).sum(axis=1),
                               rtol=1e-13)
    a, x = m.tolist(), v.tolist()
    assert rot3.mat_t_vec(m, v)[1] == a[0][1] * x[0] + a[1][1] * x[1] + a[2][1] * x[2]
    r = rows.tolist()
    assert rot3.rotate_rows(rows, m)[4, 2] == r[4][0] * a[2][0] + r[4][1] * a[2][1] + \
        r[4][2] * a[2][2]
