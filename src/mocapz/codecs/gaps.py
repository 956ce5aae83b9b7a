"""Gaps (missing marker samples), shared by every codec: filling for the encoders, and the two mask codings.

Samples missing in the source stay missing after decoding. Encoders fill them for their models: by linear
interpolation in time (:func:`fill_linear`; constant before the first and after the last observed sample,
0 where never observed) or by holding the last observed value (:func:`fill_hold`, whose integer second
differences stay small). The mask travels as packed bits (:func:`pack_mask`, any shape) or as run lengths
per marker (:func:`encode_mask`, small for long gaps).
"""

from __future__ import annotations

import math

import numpy as np

from mocapz.errors import FormatError
from mocapz.format.entropy import pack_uint64, unpack_uint64


def fill_linear(x: np.ndarray, missing: np.ndarray) -> np.ndarray:
    """``(frames, columns)`` values with the ``missing`` ones filled per column by linear interpolation in time.

    Samples before the first / after the last observed one take its value; a column never observed is 0.
    """
    out = np.array(x, dtype=np.float64, copy=True)
    t = np.arange(len(out), dtype=np.float64)
    for c in np.flatnonzero(missing.any(axis=0)):
        ok = ~missing[:, c]
        out[:, c] = np.interp(t, t[ok], out[ok, c]) if ok.any() else 0.0
    return out


def fill_positions(positions: np.ndarray) -> np.ndarray:
    """``(frames, markers, 3)`` positions with every incomplete sample filled (:func:`fill_linear`)."""
    t, m, _ = positions.shape
    bad = ~np.isfinite(positions).all(axis=2)
    return fill_linear(positions.reshape(t, 3 * m), np.repeat(bad, 3, axis=1)).reshape(t, m, 3)


def fill_hold(x: np.ndarray, missing: np.ndarray) -> np.ndarray:
    """``(frames, columns)`` values with each missing one replaced by the last observed value of its column
    (the first observed value before it; 0 for a column never observed)."""
    filled = np.array(x, dtype=np.float64, copy=True)
    for c in np.flatnonzero(missing.any(axis=0)):
        ok = np.flatnonzero(~missing[:, c])
        if ok.size == 0:
            filled[:, c] = 0.0
            continue
        idx = np.maximum.accumulate(np.where(~missing[:, c], np.arange(len(filled)), -1))
        idx[idx < 0] = ok[0]
        filled[:, c] = filled[idx, c]
    return filled


def pack_mask(mask: np.ndarray) -> bytes:
    """A boolean mask of any shape as packed bits (row-major), zstd-coded integers."""
    return pack_uint64(np.packbits(mask.ravel()).astype(np.uint64))


def unpack_mask(data: bytes, shape: tuple[int, ...]) -> np.ndarray:
    """Inverse of :func:`pack_mask` for a mask of ``shape``."""
    size = math.prod(shape)
    flat = np.unpackbits(unpack_uint64(data, -(-size // 8)).astype(np.uint8))
    return flat[:size].astype(bool).reshape(shape)


def encode_mask(missing: np.ndarray) -> bytes:
    """Run lengths of a ``(T, M)`` boolean missing mask (per marker: observed run first)."""
    runs: list[int] = []
    counts: list[int] = []
    for m in range(missing.shape[1]):
        col = missing[:, m].astype(np.int8)
        edges = np.flatnonzero(np.diff(col)) + 1
        bounds = np.concatenate([[0], edges, [len(col)]])
        r = np.diff(bounds).tolist()
        if len(col) and col[0]:
            r = [0] + r
        counts.append(len(r))
        runs.extend(r)
    return pack_uint64(np.asarray(counts + runs, dtype=np.uint64))


def decode_mask(data: bytes, frames: int, markers: int) -> np.ndarray:
    """Inverse of :func:`encode_mask`: ``(T, M)`` True where missing."""
    v = unpack_uint64(data, at_most=markers * (frames + 2))  # a marker has at most frames + 1 runs
    if v.size < markers or np.any(v[:markers] > frames + 1) or np.any(v[markers:] > frames):
        raise FormatError(None, "corrupted gap mask")
    counts, runs = v[:markers].astype(np.int64), v[markers:].astype(np.int64)
    if counts.sum() != runs.size:
        raise FormatError(None, "corrupted gap mask (run count)")
    out = np.zeros((frames, markers), dtype=bool)
    pos = 0
    for m in range(markers):
        r = runs[pos : pos + counts[m]]
        pos += counts[m]
        if r.sum() != frames:
            raise FormatError(None, "corrupted gap mask (run lengths)")
        col = np.repeat(np.arange(len(r)) % 2 == 1, r)
        out[:, m] = col
    return out
