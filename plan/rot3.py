"""Rotations and 3-vectors as explicit scalar arithmetic: the same bits on every CPU.

A matrix product through numpy (``@``, ``dot``, ``einsum``) goes to BLAS, and OpenBLAS picks
its kernels by CPU (Haswell, SkylakeX, ...): the sums of products come out in a different
order, with or without fused multiply-adds, and the last bits of a result change from one
machine to the next. Every value a node publishes that goes through a rotation is computed
here instead, as plain multiplications and additions in a fixed order (IEEE-754 rounds each
of them the same everywhere), which for 3 x 3 is also cheaper than a BLAS call.
tests/test_architecture.py keeps matrix products out of the packages that publish values.

Matrices are row-major 3 x 3 (anything ``m[i][j]`` or ``m[i, j]`` indexes, e.g. MuJoCo's
``xmat.reshape(3, 3)``); vectors have three items. Scalar results are Python floats.
"""

from __future__ import annotations

import numpy as np

Vec3 = tuple[float, float, float]
Mat3 = tuple[Vec3, Vec3, Vec3]


def _rows(m) -> list[list[float]]:
    return np.asarray(m, dtype=np.float64).reshape(3, 3).tolist()


def mat_vec(m, v) -> Vec3:
    """M v."""
    (a, b, c), (d, e, f), (g, h, i) = _rows(m)
    x, y, z = (float(t) for t in v)
    return (a * x + b * y + c * z, d * x + e * y + f * z, g * x + h * y + i * z)


def mat_t_vec(m, v) -> Vec3:
    """M^T v (a world vector in the frame whose axes are M's columns)."""
    (a, b, c), (d, e, f), (g, h, i) = _rows(m)
    x, y, z = (float(t) for t in v)
    return (a * x + d * y + g * z, b * x + e * y + h * z, c * x + f * y + i * z)


def mat_mul(m, n) -> Mat3:
    """M N."""
    a, b = _rows(m), _rows(n)
    return tuple(tuple(a[r][0] * b[0][c] + a[r][1] * b[1][c] + a[r][2] * b[2][c]
                       for c in range(3)) for r in range(3))  # type: ignore[return-value]


def mat_t_mul(m, n) -> Mat3:
    """M^T N."""
    a, b = _rows(m), _rows(n)
    return tuple(tuple(a[0][r] * b[0][c] + a[1][r] * b[1][c] + a[2][r] * b[2][c]
                       for c in range(3)) for r in range(3))  # type: ignore[return-value]


def rotate_rows(points: np.ndarray, m) -> np.ndarray:
    """Each row p of an (N, 3) array turned by M (M p, i.e. ``points @ M.T``), elementwise.

    numpy's elementwise multiply and add round every element the same whatever SIMD width
    it runs with, unlike a BLAS product.
    """
    (a, b, c), (d, e, f), (g, h, i) = _rows(m)
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    out = np.empty((len(points), 3), dtype=np.float64)
    out[:, 0] = x * a + y * b + z * c
    out[:, 1] = x * d + y * e + z * f
    out[:, 2] = x * g + y * h + z * i
    return out


def row_dots(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The dot product of each row of two (N, 3) arrays, elementwise."""
    return p[:, 0] * q[:, 0] + p[:, 1] * q[:, 1] + p[:, 2] * q[:, 2]
