"""Compiled (numba) point errors: :func:`mocapz.metrics.figures.point_errors`'s numbers, to the bit, in one pass (no
``(frames, points, 3)`` differences). NumPy's ``np.linalg.norm(a - b, axis=-1)`` sums the three squares in order,
``sqrt((d0 d0 + d1 d1) + d2 d2)``; so does the kernel (a NaN gives NaN), and :func:`farthest` (the correction's
levers). Imported only where numba is installed; :mod:`mocapz.aot` compiles them ahead of time (alias ``err``), and
their callers take them only from there."""

# ruff: noqa: ANN001
from __future__ import annotations

import math

from numba import njit

jit = njit(cache=True, nogil=True, error_model="numpy")


@jit
def point_errors(a, b, out) -> None:
    """Euclidean distances ``out`` ``(frames, points)`` of positions ``a`` and ``b`` ``(frames, points, 3)``."""
    for f in range(a.shape[0]):
        for p in range(a.shape[1]):
            d0 = a[f, p, 0] - b[f, p, 0]
            d1 = a[f, p, 1] - b[f, p, 1]
            d2 = a[f, p, 2] - b[f, p, 2]
            out[f, p] = math.sqrt((d0 * d0 + d1 * d1) + d2 * d2)


@jit
def farthest(positions, joints, points, out) -> None:
    """``out[k]``: the largest distance over the frames of ``positions`` ``(frames, points, 3)`` between point
    ``points[k]`` and point ``joints[k]`` (``np.linalg.norm(a - b, axis=-1).max()``'s number: NaN if one is NaN)."""
    for k in range(joints.size):
        j, p = joints[k], points[k]
        best = -math.inf
        for f in range(positions.shape[0]):
            d0 = positions[f, p, 0] - positions[f, j, 0]
            d1 = positions[f, p, 1] - positions[f, j, 1]
            d2 = positions[f, p, 2] - positions[f, j, 2]
            d = math.sqrt((d0 * d0 + d1 * d1) + d2 * d2)
            if d > best or d != d:
                best = d
                if d != d:
                    break
        out[k] = best
