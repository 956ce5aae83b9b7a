"""Gaps (missing marker samples): filling for the encoder and the run-length coded mask.

Samples missing in the source stay missing after decoding: the mask travels as run lengths per marker.
For segmentation and the closed-loop reference the encoder fills gaps by linear interpolation in time
(constant before the first and after the last observed sample); the filled values are never counted by
the clustering (their observation weight is 0).
"""

from __future__ import annotations

import numpy as np

from mocapz.errors import FormatError
from mocapz.format.entropy import pack_uint64, unpack_uint64


def fill_gaps(positions: np.ndarray) -> np.ndarray:
    """``(T, M, 3)`` positions with NaN samples filled by linear interpolation over time (0 if never seen)."""
    out = positions.copy()
    t = positions.shape[0]
    frames = np.arange(t)
    bad = ~np.isfinite(positions).all(axis=2)
    for m in np.flatnonzero(bad.any(axis=0)):
        ok = ~bad[:, m]
        if not ok.any():
            out[:, m] = 0.0
            continue
        for c in range(3):
            out[:, m, c] = np.interp(frames, frames[ok], positions[ok, m, c])
    return out


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
    v = unpack_uint64(data).astype(np.int64)
    if v.size < markers:
        raise FormatError(None, "corrupted gap mask")
    counts, runs = v[:markers], v[markers:]
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
