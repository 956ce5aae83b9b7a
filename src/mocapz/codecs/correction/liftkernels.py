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
def _level(n: int, level: int) -> tuple[int, int, int]:
    """Level ``level`` of ``n`` padded samples: its spacing ``h``, its new samples' count ``m`` (the odd multiples
    of ``h``) and ``hi``: samples ``1 <= t < hi`` have both ``3h`` neighbours (the 4-point filter)."""
    h = 1 << level
    m = len(range(h, n - 1, 2 * h))
    return h, m, min(m, (n - 1 - 4 * h) // (2 * h) + 1)


@jit
def _predict(y, i: int, h: int, c: int, four: bool) -> float:
    """Sample ``i``'s prediction (column ``c``) from the decoded samples ``h`` away: the 4-point
    Deslauriers-Dubuc filter where ``four`` (both ``3h`` neighbours inside), else the mean of the two next."""
    left = y[i - h, c]
    right = y[i + h, c]
    if four:
        return (9.0 * (left + right) - (y[i - 3 * h, c] + y[i + 3 * h, c])) / 16.0
    return 0.5 * (left + right)


@jit
def _across(y, h: int, c: int, hi: int, level: int, ghost, pred: float) -> float:
    """The first new sample's prediction (row ``h``) across a continued clip's edge: the 4-point filter with
    level ``level``'s ghost ``ghost[level, c]`` (the decoded value ``2h`` rows before row 0) where there is one
    and the row ``4h`` (``hi >= 1``), else ``pred`` (:func:`~.lifting._predict`)."""
    if hi < 1 or level >= ghost.shape[0]:
        return pred
    g = ghost[level, c]
    if math.isnan(g):
        return pred
    return (9.0 * (y[0, c] + y[2 * h, c]) - (g + y[4 * h, c])) / 16.0


@jit
def details(xp, tp, y, q, levels: int, factors, step_scale: float, row0: int, ghost) -> None:
    """Code every detail level, coarse to fine, into ``y`` and ``q`` (rows from ``row0``, after the knots).

    ``factors[l]``: the tolerance share of level ``l`` (:func:`~.lifting.level_factor`); ``step_scale``:
    :data:`~.lifting.STEP`. ``y`` holds the decoded knots (every ``2 ** levels``-th row) on entry. ``ghost``
    ``(ghost levels, columns)``: a continued clip's ghosts (:func:`_across`; none: ``(0, columns)``)."""
    n, cols = xp.shape
    row = row0
    for level in range(levels - 1, -1, -1):
        h, m, hi = _level(n, level)
        f = factors[level]
        for c in range(cols):
            for t in range(m):
                i = h + 2 * h * t
                pred = _predict(y, i, h, c, 1 <= t < hi)
                if t == 0:
                    pred = _across(y, h, c, hi, level, ghost, pred)
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


@jit
def decode_details(q, tol_col, halves, lev, groups, y, levels: int, factors, step_scale: float, row0: int,
                   frames: int, big: float, ghost) -> None:
    """:func:`~.lifting.decode_table`'s detail levels, coarse to fine, into ``y`` ``(n, columns)`` (the decoded
    knots on entry): the integers ``q`` (rows from ``row0``), the tolerance of frame ``t``, column ``c``
    ``tol_col[c] * halves[lev[t, groups[c]]]`` capped at ``big`` as ``np.minimum`` does (NaN stays NaN), rows
    past ``frames`` repeating the last as :func:`~.lifting._pad` does. The same float operations in the same
    order as the NumPy path of :func:`~.lifting.decode`: the same bits. ``ghost``: as in :func:`details`."""
    n, cols = y.shape
    row = row0
    for level in range(levels - 1, -1, -1):
        h, m, hi = _level(n, level)
        t_step = step_scale * factors[level]
        for t in range(m):
            i = h + 2 * h * t
            lev_i = lev[min(i, frames - 1)]
            qr = q[row + t]
            for c in range(cols):
                pred = _predict(y, i, h, c, 1 <= t < hi)
                if t == 0:
                    pred = _across(y, h, c, hi, level, ghost, pred)
                tv = tol_col[c] * halves[lev_i[groups[c]]]
                if tv > big:
                    tv = big
                y[i, c] = pred + qr[c] * (t_step * tv)
        row += m


@jit
def rn_levels(q, recon, levels: int, lod: int, step: float, offs, wts, taps) -> None:
    """:func:`mocapz.codecs.pga.lifting.decode_rn`'s levels, coarse to fine, into ``recon`` ``(n, d)`` (sample 0
    set): each odd sample predicted by its stencil (``offs``, ``wts``, ``taps`` indexed by ``4 * (p - 3s >= 0) +
    2 * (p + s < n) + (p + 3s < n)``: the taps' offsets in level steps, weights, count), the taps added in
    stencil order, plus its stored detail ``q`` (rows from 1) times ``step`` except on the ``lod`` finest
    levels. The same float operations in the same order as the NumPy path: the same bits."""
    n, d = recon.shape
    row = 1
    for lev in range(levels - 1, -1, -1):
        s = 1 << lev
        for p in range(s, n, 2 * s):
            key = 4 * (p - 3 * s >= 0) + 2 * (p + s < n) + (p + 3 * s < n)
            for c in range(d):
                acc = wts[key, 0] * recon[p + offs[key, 0] * s, c]
                for tap in range(1, taps[key]):
                    acc = acc + wts[key, tap] * recon[p + offs[key, tap] * s, c]
                recon[p, c] = acc if lev < lod else acc + q[row, c] * step
            if lev >= lod:
                row += 1
