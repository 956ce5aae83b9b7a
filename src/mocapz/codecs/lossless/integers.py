"""Exact float <-> integer representations used by the lossless codec.

Four representations, chosen per clip, each invertible bit for bit:

* ``decimal``: ``round(value * 10**d)`` per column when the source stored ``d`` decimals;
* ``float32``: the float32 bit pattern mapped to an order-preserving integer (C3D data is float32);
* ``short decimal``: the same float32 integers for text written with few significant digits (``%g``:
  AMC files, Bandai-Namco BVH); the decoder turns each float32 back into its shortest decimal and reads
  that as float64, which gives the source's values exactly (checked when encoding);
* ``float64``: the float64 bit patterns (anything else).
"""

from __future__ import annotations

import numpy as np

REP_DECIMAL, REP_FLOAT32, REP_FLOAT64, REP_SHORT_DECIMAL = 0, 1, 2, 3
REPRESENTATIONS = (REP_DECIMAL, REP_FLOAT32, REP_FLOAT64, REP_SHORT_DECIMAL)
_POW10 = 10.0 ** np.arange(-22, 23)  # exact doubles for |e| <= 22


def shortest_decimal(f32: np.ndarray) -> np.ndarray:
    """float64 of the shortest decimal (1-9 significant digits) that rounds to each float32 value.

    Pure IEEE arithmetic (exact powers of ten, correctly rounded multiply/divide/round), so encoder and
    decoder agree bit for bit; values it cannot handle (|exponent| > 22 after scaling) come back NaN.
    """
    v = f32.astype(np.float64)
    out = np.full(v.shape, np.nan)
    out[v == 0] = v[v == 0]
    a = np.abs(v)
    ok = (a > 0) & np.isfinite(a)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        e = np.floor(np.log10(np.where(ok, a, 1.0))).astype(np.int64)
        e = np.clip(e, -40, 40)
        # correct a log10 that is one off near powers of ten
        p = _pow10(e)
        e = np.where(ok & (p > a), e - 1, e)
        e = np.where(ok & (_pow10(e + 1) <= a), e + 1, e)
        todo = ok.copy()
        for k in range(1, 10):
            digits = k - 1 - e  # decimals giving k significant digits
            good = todo & (np.abs(digits) <= 22)
            scale = _pow10(np.where(good, digits, 0))
            cand = np.where(digits >= 0, np.round(v * scale) / scale, np.round(v / _pow10(-digits)) * _pow10(-digits))
            hit = good & (cand.astype(np.float32) == f32)
            out[hit] = cand[hit]
            todo &= ~hit
    return out


def _pow10(e: np.ndarray) -> np.ndarray:
    return _POW10[np.clip(e, -22, 22) + 22]



def to_integers(values: np.ndarray, decimals: np.ndarray | None) -> tuple[int, np.ndarray]:
    """Choose a representation and convert ``(rows, cols)`` finite float64 values to int64."""
    if decimals is not None:
        scale = 10.0 ** np.asarray(decimals, dtype=np.float64)
        ints = np.round(values * scale).astype(np.int64)
        if np.array_equal(ints / scale, values):
            return REP_DECIMAL, ints
    with np.errstate(over="ignore", invalid="ignore"):
        f32 = values.astype(np.float32)
    if np.array_equal(f32.astype(np.float64), values, equal_nan=True):
        bits = f32.view(np.uint32).astype(np.int64)
        neg = bits >= (1 << 31)
        return REP_FLOAT32, np.where(neg, -(bits - (1 << 31)) - 1, bits)
    if np.array_equal(shortest_decimal(f32), values):
        bits = f32.view(np.uint32).astype(np.int64)
        neg = bits >= (1 << 31)
        return REP_SHORT_DECIMAL, np.where(neg, -(bits - (1 << 31)) - 1, bits)
    bits64 = values.view(np.int64)
    neg = bits64 < 0
    return REP_FLOAT64, np.where(neg, -(bits64 & 0x7FFFFFFFFFFFFFFF) - 1, bits64)


def from_integers(rep: int, ints: np.ndarray, decimals: np.ndarray | None) -> np.ndarray:
    """Inverse of :func:`to_integers`."""
    ints = np.asarray(ints, dtype=np.int64)
    if rep == REP_DECIMAL:
        assert decimals is not None
        return ints / 10.0 ** np.asarray(decimals, dtype=np.float64)
    neg = ints < 0
    if rep in (REP_FLOAT32, REP_SHORT_DECIMAL):
        bits = np.where(neg, (-(ints + 1)) + (1 << 31), ints).astype(np.uint32)
        f32 = bits.view(np.float32)
        return f32.astype(np.float64) if rep == REP_FLOAT32 else shortest_decimal(f32)
    mag = np.where(neg, -(ints + 1), ints)
    bits64 = np.where(neg, mag | np.int64(-0x8000000000000000), mag)
    return bits64.astype(np.int64).view(np.float64)
