"""What a block of integers costs under a quantised Laplace model: the bits the scale search of
:mod:`mocapz.format.entropy` weighs its candidate scales by, from the values, from their histogram, or from a table
of every small value's bits under every scale code (the same numbers each way)."""

from __future__ import annotations

import numpy as np

HIST_VALUES = 64  # a scale search over blocks whose absolute values are all below this works on their histogram
BIG_SHARE = 8  # a block with more than 1/BIG_SHARE of its values beyond the bits table computes them all


def _histogram(a: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """``(values (k, 1), counts (k, columns))``: how often each value ``0 .. k - 1`` occurs in each column of the
    absolute values ``a`` ``(rows, columns)`` when they are all below :data:`HIST_VALUES` (a block's costs under
    every candidate scale then come from a few values, not from every row); else ``(a, None)``."""
    cols = a.shape[1]
    top = int(a.max()) + 1 if a.size else 1
    if top > HIST_VALUES:
        return a, None
    at = a.astype(np.int64) * cols + np.arange(cols)
    counts = np.bincount(at.ravel(), minlength=top * cols).reshape(top, cols).astype(np.float64)
    return np.arange(top, dtype=np.float64)[:, None], counts


def code_bits(hist: tuple[np.ndarray, np.ndarray | None], codes: np.ndarray, steps: int, bias: int) -> np.ndarray:
    """:func:`_candidate_bits` under the scales ``2 ** ((codes - bias) / steps)`` of whole-number scale codes
    ``codes`` ``(candidates, columns)`` (floats, 0 to 255). A block's histogram is costed from a table of every
    value's bits under every code (:func:`_bits_table`: the same numbers as computed for each block, without the
    exponentials of every candidate, value and column; a few times faster)."""
    table, index = _bits_table(steps, bias), codes.astype(np.intp)
    a, counts = hist
    if counts is not None:
        bits = table[index, :a.shape[0]]  # (candidates, columns, values)
        return (np.ascontiguousarray(bits.transpose(0, 2, 1)) * counts).sum(axis=-2)
    # the values themselves (rows, columns), some beyond the table: each candidate's bits (rows, columns) from
    # the table where it holds the value, computed where not, summed down the rows as _laplace_bits does
    small = a < HIST_VALUES
    big_r, big_c = np.nonzero(~small)
    if big_r.size * BIG_SHARE > a.size:  # mostly large values: computed, as fast as looked up
        return _candidate_bits(hist, 2.0 ** ((codes - float(bias)) / steps))
    at = np.where(small, a, 0.0).astype(np.intp)
    out = np.empty(codes.shape)
    for c in range(codes.shape[0]):
        bits = table[index[c][None, :], at]
        bits[big_r, big_c] = _point_bits(a[big_r, big_c], 2.0 ** ((codes[c, big_c] - float(bias)) / steps))
        out[c] = bits.sum(axis=-2)
    return out


_TABLES: dict[tuple[int, int, int], np.ndarray] = {}


def _bits_table(steps: int, bias: int) -> np.ndarray:
    """``(256, HIST_VALUES)``: the bits :func:`_laplace_bits` charges each absolute value under each scale code
    (``s = 2 ** ((code - bias) / steps)``), made once per ``(steps, bias)``."""
    table = _TABLES.get((steps, bias, HIST_VALUES))
    if table is None:
        scales = 2.0 ** ((np.arange(256, dtype=np.float64) - float(bias)) / steps)
        a = np.arange(max(HIST_VALUES, 1), dtype=np.float64)[:, None]
        table = _TABLES[(steps, bias, HIST_VALUES)] = np.ascontiguousarray(
            np.stack([_point_bits(a, s[None, None])[:, 0] for s in scales]))
    return table


def _candidate_bits(hist: tuple[np.ndarray, np.ndarray | None], scales: np.ndarray) -> np.ndarray:
    """:func:`_laplace_bits` of a block (:func:`_histogram`) under each row of ``scales`` ``(candidates, columns)``:
    all at once from a histogram, one candidate at a time from the values themselves (a block of large values:
    every candidate's array of them at once would be many times the block)."""
    if hist[1] is not None:
        return _laplace_bits(*hist, scales)
    return np.stack([_laplace_bits(*hist, s) for s in scales])


def _laplace_bits(a: np.ndarray, counts: np.ndarray | None, scale: np.ndarray) -> np.ndarray:
    """Bits ``(columns,)`` the absolute values ``a`` ``(rows, columns)`` cost under a quantised Laplace model of
    scale ``scale`` ``(columns,)`` (each probability at least 2**-24, as the coder's); with ``counts``, ``a``
    holds distinct values ``(k, 1)`` occurring ``counts`` ``(k, columns)`` times (:func:`_histogram`). Scales
    ``(candidates, columns)`` give the bits ``(candidates, columns)`` of each candidate (the same numbers)."""
    bits = _point_bits(a, scale[..., None, :])
    return bits.sum(axis=-2) if counts is None else (bits * counts).sum(axis=-2)


def _point_bits(a: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The bits of each absolute value ``a`` under the Laplace scales ``s`` (broadcast together)."""
    zero = -np.expm1(-0.5 / s)
    other = 0.5 * np.exp(-(np.maximum(a, 0.5) - 0.5) / s) * -np.expm1(-1.0 / s)
    p = np.where(a == 0, zero, other)
    return -np.log2(np.maximum(p, 2.0**-24))
