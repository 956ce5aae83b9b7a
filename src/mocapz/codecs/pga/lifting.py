"""Multiscale (lifting-scheme) coding of trajectories on R^d and on SO(3), with quantisation.

The samples are split into even and odd ones, the odd ones predicted from the evens by cubic interpolation
at t = 1/2 (on SO(3): the tangent-spline prediction of Rahman et al.: ``r_-1, r_0, r_1, r_2`` are log-mapped
into the tangent space at ``r_0``, interpolated there and mapped back with exp), the *details* (differences,
on SO(3) ``log(pred^-1 orig)``) kept, and the scheme iterated on the evens.

Coding is closed-loop: predictions use the *reconstructed* coarser samples, so quantisation errors do not
accumulate. Dropping the ``lod`` finest levels sets their details to zero (the paper's "#LOD"): the decoder
then interpolates them smoothly.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mocapz.codecs.correction.compiled import kernels
from mocapz.codecs.pga import so3

# Prediction stencils for the odd sample at 0 from its neighbours at -3, -1, +1, +3 (in level steps),
# keyed by which of (-3, +1, +3) exist (-1 always does): (offsets, weights) of the cubic / quadratic /
# linear interpolant at t = 1/2, or an extrapolation at the end of the signal.
_STENCILS: dict[tuple[bool, bool, bool], tuple[tuple[int, ...], tuple[float, ...]]] = {
    (True, True, True): ((-3, -1, 1, 3), (-1 / 16, 9 / 16, 9 / 16, -1 / 16)),
    (False, True, True): ((-1, 1, 3), (3 / 8, 3 / 4, -1 / 8)),
    (True, True, False): ((-3, -1, 1), (-1 / 8, 3 / 4, 3 / 8)),
    (False, True, False): ((-1, 1), (1 / 2, 1 / 2)),
    (True, False, False): ((-3, -1), (-1 / 2, 3 / 2)),
    (False, False, False): ((-1,), (1.0,)),
}


@functools.cache
def _table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:data:`_STENCILS` as arrays for the compiled kernel: offsets ``(8, 4)``, weights ``(8, 4)``, tap counts
    ``(8,)``, indexed by ``4 * (-3 exists) + 2 * (+1 exists) + (+3 exists)``."""
    offs, wts, taps = np.zeros((8, 4), dtype=np.int64), np.zeros((8, 4)), np.zeros(8, dtype=np.int64)
    for (l2, r1, r2), (o, w) in _STENCILS.items():
        key = 4 * l2 + 2 * r1 + r2
        offs[key, :len(o)], wts[key, :len(w)], taps[key] = o, np.asarray(w), len(o)
    return offs, wts, taps


def n_levels(n: int) -> int:
    """Number of detail levels of an ``n``-sample signal (the coarsest level holds sample 0 only)."""
    return max(0, int(np.ceil(np.log2(max(n, 1)))))


@dataclass
class Level:
    """Odd positions of one level and their prediction stencils, grouped by stencil.

    ``groups`` holds ``(rows into positions, neighbour indices (rows, taps), weights, tap of offset -1)``.
    """

    positions: np.ndarray
    groups: list[tuple[np.ndarray, np.ndarray, np.ndarray, int]]


@functools.lru_cache(maxsize=64)
def plan(n: int) -> list[Level]:
    """Prediction plan for ``n`` samples, coarsest level first (cached: treat as read-only)."""
    levels = []
    for lev in range(n_levels(n) - 1, -1, -1):
        s = 1 << lev
        pos = np.arange(s, n, 2 * s)
        l2, r1, r2 = pos - 3 * s >= 0, pos + s < n, pos + 3 * s < n
        groups = []
        for key, (offs, w) in _STENCILS.items():
            rows = np.flatnonzero((l2 == key[0]) & (r1 == key[1]) & (r2 == key[2]))
            if rows.size:
                nb = pos[rows, None] + np.asarray(offs)[None] * s
                groups.append((rows, nb, np.asarray(w), offs.index(-1)))
        levels.append(Level(pos, groups))
    return levels


def _predict_rn(recon: np.ndarray, level: Level, first: int = 0, stop: int | None = None) -> np.ndarray:
    """Predictions of the level's odd samples ``[first, stop)`` (all by default): the stencils' weighted sums of
    strided views of the even samples (every stencil's rows are consecutive; the taps are added in stencil
    order)."""
    pos = level.positions
    stop = pos.size if stop is None else stop
    pred = np.empty((max(stop - first, 0), recon.shape[1]))
    if not pred.shape[0]:
        return pred
    s = int(pos[0])
    even = recon[0 :: 2 * s]  # even[t] is sample 2st; odd row t is sample s + 2st
    for rows, nb, w, _ in level.groups:
        r0, r1 = max(int(rows[0]), first), min(int(rows[-1]) + 1, stop)
        if r1 <= r0:
            continue
        if int(rows[-1]) + 1 - int(rows[0]) != rows.size:  # pragma: no cover - stencil rows are always consecutive
            raise AssertionError("stencil rows are not consecutive")
        acc = None
        for tap, wt in enumerate(w):
            e0 = int(nb[r0 - int(rows[0]), tap]) // (2 * s)  # the tap's sample for row r0 (an even multiple of s)
            term = wt * even[e0 : e0 + (r1 - r0)]
            acc = term if acc is None else acc + term
        pred[r0 - first:r1 - first] = acc
    return pred


def _predict_so3(recon: np.ndarray, level: Level, first: int = 0, stop: int | None = None) -> np.ndarray:
    stop = level.positions.size if stop is None else stop
    pred = np.empty((max(stop - first, 0), 3, 3))
    for rows, nb, w, k0 in level.groups:
        keep = (rows >= first) & (rows < stop)
        if keep.all():
            r0 = recon[nb[:, k0]]
            t = so3.log(np.swapaxes(r0, -1, -2)[:, None] @ recon[nb])
            pred[rows - first] = r0 @ so3.exp(np.tensordot(t, w, axes=([1], [0])))
        elif keep.any():  # a window: the rows it needs, in the tensordot of the whole group's shape (BLAS sums a
            # row as the full decode does only in a matrix of the same shape), the other rows zeros
            r0 = recon[nb[keep, k0]]
            t = np.zeros((rows.size, *nb.shape[1:], 3))
            t[keep] = so3.log(np.swapaxes(r0, -1, -2)[:, None] @ recon[nb[keep]])
            pred[rows[keep] - first] = r0 @ so3.exp(np.tensordot(t, w, axes=([1], [0]))[keep])
    return pred


def _pyramid(n: int, lod: int, recon: np.ndarray, predict: Callable[..., np.ndarray],
             refine: Callable[[np.ndarray, np.ndarray], np.ndarray], window: tuple[int, int] | None = None) -> None:
    """The coarse-to-fine pass shared by every coder and decoder: predict each level's odd samples from
    the reconstruction so far, then ``refine(positions, prediction)`` (code or apply the details), except on
    the ``lod`` finest levels, which keep the prediction. ``window``: only the samples frames ``[a, b)`` need
    (:func:`reach`; the others are left as they are), ``refine`` then takes the level's index and row range
    first."""
    levels = plan(n)
    ranges = reach(n, *window) if window is not None else None
    for li, level in enumerate(levels):
        dropped = len(levels) - 1 - li < lod
        if ranges is None:
            pred = predict(recon, level)
            recon[level.positions] = pred if dropped else refine(level.positions, pred)
            continue
        lo, hi = ranges[li]
        first, stop = np.searchsorted(level.positions, [lo, hi + 1])
        pos = level.positions[first:stop]
        pred = predict(recon, level, int(first), int(stop))
        recon[pos] = pred if dropped else refine(li, int(first), int(stop), pos, pred)


def reach(n: int, a: int, b: int) -> list[tuple[int, int]]:
    """Per level of :func:`plan` (coarsest first), the sample range ``[lo, hi]`` whose odd samples frames
    ``[a, b)`` need: the frames themselves at the finest level, and at each coarser one the range below widened
    by the 4-tap stencils' reach (3 steps of the level below each way)."""
    lo, hi, out = a, b - 1, []
    for lev in range(n_levels(n)):  # finest first
        out.append((lo, hi))
        s = 1 << lev
        lo, hi = max(0, lo - 3 * s), min(n - 1, hi + 3 * s)
    return out[::-1]


def _level_rows(n: int, lod: int) -> list[int]:
    """The first integer row of every level of :func:`plan`'s details (coarsest first; row 0 is sample 0)."""
    levels, out, row = plan(n), [], 1
    for li, level in enumerate(levels):
        out.append(row)
        if len(levels) - 1 - li >= lod:
            row += level.positions.size
    return out


class _Reader:
    """Hands out the stored detail rows level by level."""

    def __init__(self, q: np.ndarray) -> None:
        self.q, self.pos = q, 1

    def take(self, m: int) -> np.ndarray:
        out = self.q[self.pos : self.pos + m]
        self.pos += m
        return out


def encode_rn(x: np.ndarray, step: float, lod: int) -> tuple[np.ndarray, np.ndarray]:
    """Quantised multiscale coefficients of ``x`` ``(n, d)`` and its reconstruction.

    Returns integer rows ``(n - dropped, d)`` (sample 0 first, then the kept details, coarse to fine)
    and the reconstruction ``(n, d)`` the decoder will produce.
    """
    recon = np.zeros_like(x, dtype=np.float64)
    rows = [np.round(x[:1] / step)]
    recon[0] = rows[0][0] * step

    def refine(pos: np.ndarray, pred: np.ndarray) -> np.ndarray:
        rows.append(np.round((x[pos] - pred) / step))
        return pred + rows[-1] * step

    _pyramid(x.shape[0], lod, recon, _predict_rn, refine)
    return np.concatenate(rows).astype(np.int64), recon


def decode_rn(q: np.ndarray, n: int, step: float, lod: int) -> np.ndarray:
    """Inverse of :func:`encode_rn` (by the compiled kernel when loaded: the same bits)."""
    recon = np.zeros((n, q.shape[1]))
    recon[0] = q[0] * step
    kern = kernels(n, "liftkernels") if q.shape[0] == coefficient_rows(n, lod) and q.dtype == np.int64 else None
    if kern is not None:
        kern.rn_levels(np.ascontiguousarray(q), recon, n_levels(n), lod, float(step), *_table())
        return recon
    reader = _Reader(q)
    _pyramid(n, lod, recon, _predict_rn, lambda pos, pred: pred + reader.take(pos.size) * step)
    return recon


def encode_so3(r: np.ndarray, step: float, lod: int) -> tuple[np.ndarray, np.ndarray]:
    """Multiscale coding of rotations ``(n, 3, 3)``: integer rows ``(rows, 3)`` and the reconstruction."""
    recon = np.empty_like(r)
    rows = [np.round(so3.log(r[:1]) / step)]
    recon[0] = so3.exp(rows[0] * step)[0]

    def refine(pos: np.ndarray, pred: np.ndarray) -> np.ndarray:
        rows.append(np.round(so3.log(np.swapaxes(pred, -1, -2) @ r[pos]) / step))
        return pred @ so3.exp(rows[-1] * step)

    _pyramid(r.shape[0], lod, recon, _predict_so3, refine)
    return np.concatenate(rows).astype(np.int64), recon


def decode_so3(q: np.ndarray, n: int, step: float, lod: int) -> np.ndarray:
    """Inverse of :func:`encode_so3`."""
    recon = np.empty((n, 3, 3))
    recon[0] = so3.exp(q[:1] * step)[0]
    reader = _Reader(q)
    _pyramid(n, lod, recon, _predict_so3, lambda pos, pred: pred @ so3.exp(reader.take(pos.size) * step))
    return recon


def decode_rn_window(q: np.ndarray, n: int, step: float, lod: int, a: int, b: int) -> np.ndarray:
    """Rows ``[a, b)`` of :func:`decode_rn`, to the bit, computing only the samples they need."""
    recon = np.zeros((n, q.shape[1]))
    recon[0] = q[0] * step
    starts = _level_rows(n, lod)

    def refine(li: int, first: int, stop: int, pos: np.ndarray, pred: np.ndarray) -> np.ndarray:
        return pred + q[starts[li] + first:starts[li] + stop] * step

    _pyramid(n, lod, recon, _predict_rn, refine, (a, b))
    return recon[a:b]


def decode_so3_window(q: np.ndarray, n: int, step: float, lod: int, a: int, b: int) -> np.ndarray:
    """Rows ``[a, b)`` of :func:`decode_so3`, to the bit, computing only the samples they need."""
    recon = np.empty((n, 3, 3))
    recon[0] = so3.exp(q[:1] * step)[0]
    starts = _level_rows(n, lod)

    def refine(li: int, first: int, stop: int, pos: np.ndarray, pred: np.ndarray) -> np.ndarray:
        return pred @ so3.exp(q[starts[li] + first:starts[li] + stop] * step)

    _pyramid(n, lod, recon, _predict_so3, refine, (a, b))
    return recon[a:b]


def coefficient_rows(n: int, lod: int) -> int:
    """Number of integer rows :func:`encode_rn` / :func:`encode_so3` produce (counted without building the
    plan: level ``l`` holds the samples ``2**l, 3 * 2**l, ...`` below ``n``; the ``lod`` finest are dropped)."""
    return 1 + sum(len(range(1 << lev, n, 2 << lev)) for lev in range(max(lod, 0), n_levels(n)))
