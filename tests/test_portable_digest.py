"""A digest does not depend on which CPU kernels the machine's libraries pick: nav without its
camera gives one digest whichever kernels OpenBLAS is told to use (OPENBLAS_CORETYPE) and with
numpy's CPU dispatch cut back to its baseline (NPY_DISABLE_CPU_FEATURES), in-process and
multi-process. Every run is a real cosim-orchestrate process, so the variables are read
where they take effect: at the start of the interpreters that load numpy and OpenBLAS.

OpenBLAS runs a forced kernel whether or not the CPU has its instructions (an AVX-512 kernel on
a CPU without AVX-512 dies with SIGILL), so only the kernels this CPU can run are compared: read
from numpy's own CPU detection (CPUID and the OS's support for the registers, as OpenBLAS checks
them), at least two on any x86-64 (Prescott needs only SSE3)."""

from __future__ import annotations

import yaml

from tests.helpers import nav_without_camera_doc, orchestrate

# numpy's dispatch targets above its x86-64 baseline; names it does not know are ignored
# with a warning on a machine without them, so this works on any x86-64.
NPY_BASELINE_ONLY = "X86_V3 X86_V4 AVX512_ICL AVX512_SPR"

# OpenBLAS's x86-64 core types, newest first, with the CPU features (numpy's names) each
# kernel's instructions need (OpenBLAS's own checks: driver/others/dynamic.c).
OPENBLAS_KERNELS = (
    ("SkylakeX", frozenset({"AVX512F", "AVX512CD", "AVX512BW", "AVX512DQ", "AVX512VL"})),
    ("Haswell", frozenset({"AVX2", "FMA3"})),
    ("Sandybridge", frozenset({"AVX"})),
    # SSE3; numpy's OpenBLAS runs its generic SSE kernel (Katmai) for it
    ("Prescott", frozenset({"SSE3"})),
)


def cpu_features() -> frozenset[str]:
    """The features this CPU has and the OS enables, as numpy detected them at import."""
    from numpy._core._multiarray_umath import __cpu_features__

    return frozenset(name for name, present in __cpu_features__.items() if present)


def runnable_kernels(features: frozenset[str]) -> list[str]:
    """The OpenBLAS core types whose instructions a CPU with these features has, newest
    first."""
    return [name for name, needs in OPENBLAS_KERNELS if needs <= features]


def test_runnable_kernels_leave_out_what_the_cpu_lacks():
    """An AVX2 machine without AVX-512 (an AMD Zen 2/3 laptop, an older Intel server) gets no
    SkylakeX; an AVX-512 machine gets all four; a plain SSE3 machine gets Prescott."""
    zen3 = frozenset({"SSE", "SSE2", "SSE3", "SSSE3", "AVX", "F16C", "FMA3", "AVX2"})
    assert runnable_kernels(zen3) == ["Haswell", "Sandybridge", "Prescott"]
    skx = zen3 | {"AVX512F", "AVX512CD", "AVX512BW", "AVX512DQ", "AVX512VL", "AVX512_SKX"}
    assert runnable_kernels(skx) == ["SkylakeX", "Haswell", "Sandybridge", "Prescott"]
    assert runnable_kernels(frozenset({"SSE2", "SSE3"})) == ["Prescott"]
    assert "SSE3" in cpu_features()  # every x86-64 numpy runs on has it


def nav_without_camera(tmp_path, duration: str = "1s"):
    """nav minus its camera (rendered pixels depend on the renderer, not the CPU), short."""
    doc = nav_without_camera_doc(duration)
    path = tmp_path / "nav_nocam.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_one_digest_whatever_blas_kernels_and_numpy_cpu_features(tmp_path):
    kernels = runnable_kernels(cpu_features())
    assert len(kernels) >= 2, f"an x86-64 CPU runs at least two OpenBLAS kernels, got {kernels}"
    newest, oldest = kernels[0], kernels[-1]
    scenario = nav_without_camera(tmp_path)
    runs = {kernel: ({"OPENBLAS_CORETYPE": kernel}, ["--in-process"]) for kernel in kernels}
    runs[f"{oldest}, numpy baseline"] = ({"OPENBLAS_CORETYPE": oldest,
                                          "NPY_DISABLE_CPU_FEATURES": NPY_BASELINE_ONLY},
                                         ["--in-process"])
    runs[f"{newest}, multi-process"] = ({"OPENBLAS_CORETYPE": newest}, [])
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
