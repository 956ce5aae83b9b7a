"""Compiled (numba) point errors: :func:`mocapz.metrics.figures.point_errors`'s numbers, to the bit, in one pass (no
``(frames, points, 3)`` differences). NumPy's ``np.linalg.norm(a - b, axis=-1)`` sums the three squares in order,
``sqrt((d0 d0 + d1 d1) + d2 d2)``; so does the kernel (a NaN gives NaN). Imported only where numba is installed;
:mod:`mocapz.aot` compiles it ahead of time (alias ``err``), and the metrics take it only from there."""

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
