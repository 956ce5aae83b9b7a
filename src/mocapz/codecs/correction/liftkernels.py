"""Compiled (numba) kernel of :func:`mocapz.codecs.correction.lifting.quantise`'s detail levels (imported only
when numba is installed; a module-level function, so that numba's on-disk cache keeps it across processes).

It does, one column and one sample at a time in one pass per level, what the NumPy path does with a dozen
array steps per level (each a temporary of the level's samples): the same float operations in the same
order, so the integers and the decoded residual are the NumPy path's to the bit (tests/test_correction_jit.py).

Shapes: ``xp``, ``tp``, ``y`` ``(n, columns)`` (the padded residual, tolerances, decoded samples; ``n = k *
2 ** levels + 1``), ``q`` ``(n, columns)`` int64 (the integers, in :func:`~.lifting.quantise`'s row order).
"""

# ruff: noqa: ANN001
from __future__ import annotations

import math

from numba import njit

jit = njit(cache=True, nogil=True, error_model="numpy")


@jit
def details(xp, tp, y, q, levels: int, factors, step_scale: float, row0: int) -> None:
    """Code every detail level, coarse to fine, into ``y`` and ``q`` (rows from ``row0``, after the knots).

    ``factors[l]``: the tolerance share of level ``l`` (:func:`~.lifting.level_factor`); ``step_scale``:
    :data:`~.lifting.STEP`. ``y`` holds the decoded knots (every ``2 ** levels``-th row) on entry."""
    n, cols = xp.shape
    row = row0
    for level in range(levels - 1, -1, -1):
        h = 1 << level
        m = len(range(h, n - 1, 2 * h))
        hi = min(m, (n - 1 - 4 * h) // (2 * h) + 1)
        f = factors[level]
        for c in range(cols):
            for t in range(m):
                i = h + 2 * h * t
                left = y[i - h, c]
                right = y[i + h, c]
                if 1 <= t < hi:
                    pred = (9.0 * (left + right) - (y[i - 3 * h, c] + y[i + 3 * h, c])) / 16.0
                else:
                    pred = 0.5 * (left + right)
                tol = f * tp[i, c]
                step = step_scale * tol
                d = xp[i, c] - pred
                k = math.ceil(max(abs(d) - tol, 0.0) / step)
                if d < 0.0:
                    k = -k
                elif d == 0.0:
                    k = 0.0
                qi = int(k)
                q[row + t, c] = qi
                y[i, c] = pred + qi * step
        row += m
