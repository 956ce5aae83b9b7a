"""What a block of integers costs under a quantised Laplace model: the bits the scale search of
:mod:`mocapz.format.entropy` weighs its candidate scales by, from the values, from their histogram, or from a table
of every small value's bits under every scale code (the same numbers each way)."""

from __future__ import annotations

from typing import Any

import numpy as np

HIST_VALUES = 64  # a scale search over blocks whose absolute values are all below this works on their histogram
BIG_SHARE = 8  # a block with more than 1/BIG_SHARE of its values beyond the bits table computes them all
SEARCH_BITS = 1 << 18  # the bits :func:`scale_codes` costs at once (blocks x candidates x values x columns: 2 MB)


def scale_codes(values: np.ndarray, block: int, steps: int, bias: int, offsets: range, top: int,
                kernels: Any = None) -> np.ndarray:
    """Quantised Laplace scale codes ``(blocks, columns)`` int64 (``s = 2 ** ((q - bias) / steps)``, ``0 <= q <=
    top``): per block of ``block`` rows and column of the integers ``values`` ``(rows, columns)``, of the codes
    ``offsets`` away from the one of the mean absolute value, the one under which the block's values cost the
    fewest bits (:func:`code_bits`; the first of the cheapest, in ``offsets``' order). Sparse columns (mostly
    zeros, a few larger values) cost less with a wider scale than their mean suggests.

    The whole blocks whose values are all below :data:`HIST_VALUES` are costed together, a few at a time, from
    their histograms (each block's histogram padded with values it does not hold: their bits count zero times,
    added after the others, so every sum is the one of the block alone); a block of larger values and the last,
    partial block are costed alone (:func:`_block_codes`): the same codes either way. ``kernels``: the range coder's
    compiled kernels (:mod:`.rangekernels`), whose ``histogram_codes`` costs those whole blocks and ``block_codes``
    the whole blocks of larger values (the same codes, without the bits of every block, candidate, value and column
    made as arrays), or None."""
    rows, cols = values.shape
    nb = max(1, -(-rows // block))
    q = np.zeros((nb, cols), dtype=np.int64)
    off = np.asarray(offsets, dtype=np.float64)
    whole = rows // block if cols else 0
    per = max(1, SEARCH_BITS // (off.size * max(HIST_VALUES, 1) * max(cols, 1)))
    if kernels is not None:  # no bits arrays: blocks at once up to a float copy of 2 ** 21 values
        per = max(1, 8 * SEARCH_BITS // (block * max(cols, 1)))
    for b0 in range(0, whole, per):
        b1 = min(whole, b0 + per)
        part = values[b0 * block:b1 * block]
        a = np.abs(part).astype(np.float64).reshape(b1 - b0, block, cols)
        guess = np.round(np.log2(np.maximum(a.mean(axis=1), 2.0**-6)) * steps) + bias  # (blocks, columns)
        codes = np.clip(guess[:, None, :] + off[None, :, None], 0, top)  # (blocks, candidates, columns)
        tops = a.max(axis=(1, 2))
        if kernels is not None:
            kernels.histogram_codes(np.ascontiguousarray(part, dtype=np.int64), block, codes,
                                    _bits_table(steps, bias), tops < HIST_VALUES, q[b0:b1])
            for b in np.flatnonzero(tops >= HIST_VALUES):
                q[b0 + b] = _compiled_block_codes(part[b * block:(b + 1) * block], a[b], codes[b], steps, bias,
                                                  kernels)
            continue
        cost = np.empty(codes.shape)
        small = np.flatnonzero(tops < HIST_VALUES)
        if small.size:
            cost[small] = _histogram_costs(a[small], codes[small], steps, bias)
        for b in np.flatnonzero(tops >= HIST_VALUES):
            cost[b] = code_bits((a[b], None), codes[b], steps, bias)
        q[b0:b1] = np.take_along_axis(codes, np.argmin(cost, axis=1)[:, None, :], axis=1)[:, 0, :]
    for b in range(whole, nb):
        q[b] = _block_codes(values[b * block:(b + 1) * block], cols, steps, bias, off, top)
    return q


def _compiled_block_codes(values: np.ndarray, a: np.ndarray, codes: np.ndarray, steps: int, bias: int,
                          kernels: Any) -> np.ndarray:
    """:func:`code_bits`' choice ``(columns,)`` for a whole block ``values`` ``(rows, columns)`` with values beyond
    the table (``a``: their absolute values as floats) by the compiled ``block_codes``: the bits of those values
    computed here (:func:`_point_bits`, as :func:`code_bits` computes them), the others' from the table (the
    numbers :func:`code_bits` computes for them where most values are large: tests/test_entropy_speed_equal.py)."""
    big_r, big_c = np.nonzero(a >= HIST_VALUES)
    big_bits = _point_bits(a[big_r, big_c][None, :], 2.0 ** ((codes[:, big_c] - float(bias)) / steps))
    out = np.empty(codes.shape[1], dtype=np.int64)
    kernels.block_codes(np.ascontiguousarray(values, dtype=np.int64), np.ascontiguousarray(codes), _bits_table(
        steps, bias), big_r.astype(np.int64), big_c.astype(np.int64), np.ascontiguousarray(big_bits), out)
    return out


def _block_codes(values: np.ndarray, cols: int, steps: int, bias: int, off: np.ndarray, top: int) -> np.ndarray:
    """:func:`scale_codes` of one block ``(rows, columns)`` (none: the code of the smallest mean)."""
    blk = np.abs(values).astype(np.float64)
    m = np.maximum(blk.mean(axis=0) if blk.size else np.zeros(cols), 2.0**-6)
    guess = np.round(np.log2(m) * steps) + bias
    if not blk.size:
        return np.clip(guess, 0, top)
    codes = np.clip(guess[None, :] + off[:, None], 0, top)  # (offsets, cols)
    cost = code_bits(_histogram(blk), codes, steps, bias)
    return codes[np.argmin(cost, axis=0), np.arange(cols)]


def _histogram_costs(a: np.ndarray, codes: np.ndarray, steps: int, bias: int) -> np.ndarray:
    """:func:`code_bits` ``(blocks, candidates, columns)`` of blocks of absolute values ``a`` ``(blocks, rows,
    columns)``, all below :data:`HIST_VALUES`, under their candidate codes ``codes`` ``(blocks, candidates,
    columns)``: from their histograms ``(blocks, values, columns)`` and the bits table."""
    nb, _, cols = a.shape
    k = int(a.max()) + 1
    at = (np.arange(nb)[:, None, None] * k + a.astype(np.int64)) * cols + np.arange(cols)
    counts = np.bincount(at.ravel(), minlength=nb * k * cols).reshape(nb, k, cols).astype(np.float64)
    bits = _bits_table(steps, bias)[codes.astype(np.intp), :k]  # (blocks, candidates, columns, values)
    return (np.ascontiguousarray(bits.transpose(0, 1, 3, 2)) * counts[:, None]).sum(axis=-2)


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
    per = max(1, SEARCH_BITS // max(a.size, 1))  # candidates at once: (candidates, rows, columns) bits
    for c0 in range(0, codes.shape[0], per):
        bits = np.take(table.ravel(), index[c0:c0 + per, None, :] * table.shape[1] + at[None])  # table[index, at]
        if big_r.size:
            scale = 2.0 ** ((codes[c0:c0 + per, big_c] - float(bias)) / steps)
            bits[:, big_r, big_c] = _point_bits(a[big_r, big_c][None, :], scale)
        out[c0:c0 + per] = bits.sum(axis=-2)
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
