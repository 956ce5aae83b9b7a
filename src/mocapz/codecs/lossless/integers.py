"""Exact float <-> integer representations used by the lossless codec.

Three representations, chosen per clip, each invertible bit for bit:

* ``decimal``: ``round(value * 10**d)`` per column when the source stored ``d`` decimals;
* ``float32``: the float32 bit pattern mapped to an order-preserving integer (C3D data is float32);
* ``float64``: the same for float64 bit patterns (anything else).
"""

from __future__ import annotations

import numpy as np

REP_DECIMAL, REP_FLOAT32, REP_FLOAT64 = 0, 1, 2



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
    if rep == REP_FLOAT32:
        bits = np.where(neg, (-(ints + 1)) + (1 << 31), ints).astype(np.uint32)
        return bits.view(np.float32).astype(np.float64)
    mag = np.where(neg, -(ints + 1), ints)
    bits64 = np.where(neg, mag | np.int64(-0x8000000000000000), mag)
    return bits64.astype(np.int64).view(np.float64)
