"""Coding of the pattern database (paper §III.D, Fig. 6) and of the root trajectory.

A pattern (``L`` frames x ``D`` values) is coded as its first frame plus ``L - 1`` delta frames. The deltas
are quantised uniformly with ``bits`` bits over their range (8 in the paper); the first frames use the
same step. Quantisation is closed-loop (each delta is taken from the previous *reconstructed* frame), so
errors do not accumulate along the pattern. The quantisation parameters travel as float32; the integer
symbols are entropy coded by the range coder of :mod:`mocapz.format.entropy` (the deltas after a lossless
difference along time, which keeps the adaptive Laplace models narrow).

The root trajectory (absolute positions of the root marker, or the root joint's channels) is coded per
frame with closed-loop second-order prediction and a uniform step: every reconstructed value is within
half a step of the original.
"""

from __future__ import annotations

import struct

import numpy as np

from mocapz.codecs.patterns.gaussian import gaussian_smooth
from mocapz.errors import FormatError
from mocapz.format.entropy import (
    decode_int_matrix,
    encode_int_matrix,
    pack_uint64,
    read_uvarint,
    unpack_uint64,
    unzigzag,
    write_uvarint,
    zigzag,
)

ROBUST = 99.5  # percentile of |delta| taken as the range (rarer, larger deltas are escaped exactly)


def delta_step(deltas: np.ndarray, bits: int) -> float:
    """Uniform quantisation step: the range of the delta values over ``2**bits - 1`` levels.

    Args:
        deltas: frame-to-frame differences of the values to code (any shape, NaN ignored).
        bits: quantisation bits.

    The range is ``[-a, a]`` with ``a`` the 99.5th percentile of ``|delta|``, so that one outlier does
    not coarsen everything; the few symbols beyond it are still coded (range coder escapes).
    """
    d = np.abs(deltas[np.isfinite(deltas)])
    span = 2.0 * float(np.percentile(d, ROBUST)) if d.size else 0.0
    return max(span / (2**bits - 1), 1e-9)


def quantise_patterns(patterns: np.ndarray, step: float, sigma: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Closed-loop first-frame + delta symbols ``(K, L, D)`` int64 and the reconstruction ``(K, L, D)``.

    A pattern's first frame is coded as a delta from the previous pattern's last decoded frame (patterns
    are stored in order of first use, so consecutive patterns usually follow each other in time). With a
    uniform quantiser and a zero start, closed-loop deltas reconstruct every value to the nearest point of
    the grid ``step * Z``, so the symbols are the differences of the grid indices.
    """
    k, length, d = patterns.shape
    q = np.round(patterns / step).astype(np.int64)
    sym = np.zeros((k, length, d), dtype=np.int64)
    if k:
        sym[:, 1:] = np.diff(q, axis=1)
        sym[0, 0] = q[0, 0]
        sym[1:, 0] = q[1:, 0] - q[:-1, -1]
    return sym, _reconstruct(sym, step, sigma)


def _reconstruct(sym: np.ndarray, step: float, sigma: float = 0.0) -> np.ndarray:
    """Decoded patterns from symbols, exactly as the decoder computes them (then smoothed over time by a
    Gaussian of ``sigma`` frames, which removes most of the quantisation noise of coarse steps)."""
    k, length, d = sym.shape
    flat = np.cumsum(sym.reshape(k * length, d), axis=0)  # grid indices, pattern after pattern
    out = flat.reshape(k, length, d) * step
    if sigma > 0 and length > 2:
        out = gaussian_smooth(out, sigma, axis=1)
    return out


def encode_patterns(patterns: np.ndarray, step: float, sigma: float = 0.0) -> tuple[bytes, np.ndarray]:
    """Code a pattern database ``(K, L, D)`` with quantisation step ``step``; bytes and decoded patterns.

    ``sigma`` (frames, stored in tenths) is the decoder's smoothing of the decoded patterns.
    """
    k, length, d = patterns.shape
    tenths = int(round(min(max(sigma, 0.0), 25.5) * 10))
    sym, rec = quantise_patterns(patterns, step, tenths / 10)
    out = bytearray(write_uvarint(k) + write_uvarint(length) + write_uvarint(d) + struct.pack("<d", step))
    out += bytes([tenths])
    if k == 0:
        return bytes(out), rec
    out += _blob(encode_int_matrix(sym[:, 0]))
    if length > 1:
        deltas = sym[:, 1:]
        resid = deltas.copy()
        resid[:, 1:] = deltas[:, 1:] - deltas[:, :-1]
        out += _blob(encode_int_matrix(resid.reshape(-1, d)))
    return bytes(out), rec


def decode_patterns(data: bytes) -> tuple[np.ndarray, int]:
    """Inverse of :func:`encode_patterns`: patterns ``(K, L, D)`` and the bytes consumed.

    The symbols are decoded (their streams checked against ``K``, ``L`` and ``D``, and bounded by their own
    size) before the database is allocated.
    """
    k, pos = read_uvarint(data, 0)
    length, pos = read_uvarint(data, pos)
    d, pos = read_uvarint(data, pos)
    if pos + 8 > len(data) or k * length * d > 1 << 31 or (k and not length):
        raise FormatError(None, "corrupted pattern database (header)")
    (step,) = struct.unpack("<d", data[pos : pos + 8])
    if not (np.isfinite(step) and step > 0):
        raise FormatError(None, f"corrupted pattern database (step {step})")
    sigma = data[pos + 8] / 10.0 if pos + 8 < len(data) else 0.0
    pos += 9
    if not k:
        return np.zeros((0, length, d)), pos
    raw, pos = _read_blob(data, pos)
    first = decode_int_matrix(raw, (k, d))
    resid = np.zeros((0, d), dtype=np.int64)
    if length > 1:
        raw, pos = _read_blob(data, pos)
        resid = decode_int_matrix(raw, (k * (length - 1), d))
    sym = np.empty((k, length, d), dtype=np.int64)
    sym[:, 0] = first
    sym[:, 1:] = np.cumsum(resid.reshape(k, length - 1, d), axis=1)
    return _reconstruct(sym, step, sigma), pos


def _blob(b: bytes) -> bytes:
    return write_uvarint(len(b)) + b


def _read_blob(data: bytes, pos: int) -> tuple[bytes, int]:
    n, pos = read_uvarint(data, pos)
    if pos + n > len(data):
        raise FormatError(None, "truncated pattern stream")
    return bytes(data[pos : pos + n]), pos + n


# ------------------------------------------------------------------ root trajectory
def encode_trajectory(values: np.ndarray, step: np.ndarray) -> tuple[bytes, np.ndarray]:
    """Closed-loop DPCM of ``(T, C)`` values with per-column steps ``(C,)``; bytes and reconstruction.

    Second-order prediction ``2 x[t-1] - x[t-2]`` from reconstructed values; with a uniform quantiser this
    reconstructs each value to its nearest grid point, so the symbols are second differences of the grid
    indices (first value and first difference as they are).
    """
    t, c = values.shape
    step = np.broadcast_to(np.asarray(step, dtype=np.float64), (c,)).copy()
    q = np.round(values / step).astype(np.int64)
    sym = q.copy()
    if t > 1:
        sym[1] = q[1] - q[0]
    if t > 2:
        sym[2:] = q[2:] - 2 * q[1:-1] + q[:-2]
    out = write_uvarint(t) + write_uvarint(c) + struct.pack(f"<{c}d", *step)
    if t:
        out += _blob(pack_uint64(zigzag(sym[0]))) + _blob(encode_int_matrix(sym[1:]))
    return out, _integrate(sym) * step


def _integrate(sym: np.ndarray) -> np.ndarray:
    """Grid indices from second-order symbols (exact integer arithmetic)."""
    q = np.zeros_like(sym)
    if len(sym):
        vel = np.cumsum(sym[1:], axis=0)  # first differences
        q[0] = sym[0]
        q[1:] = sym[0] + np.cumsum(vel, axis=0)
    return q


def decode_trajectory(data: bytes, shape: tuple[int, int] | None = None) -> tuple[np.ndarray, int]:
    """Inverse of :func:`encode_trajectory`: ``(T, C)`` values and the bytes consumed.

    ``shape``: the ``(T, C)`` the caller expects (checked before anything is decoded).
    """
    t, pos = read_uvarint(data, 0)
    c, pos = read_uvarint(data, pos)
    if shape is not None and (t, c) != tuple(shape):
        raise FormatError(None, f"corrupted root trajectory (shape {(t, c)} where {tuple(shape)} is expected)")
    if pos + 8 * c > len(data):
        raise FormatError(None, "truncated root trajectory")
    step = np.asarray(struct.unpack(f"<{c}d", data[pos : pos + 8 * c]))
    pos += 8 * c
    if t == 0:
        return np.zeros((0, c)), pos
    raw, pos = _read_blob(data, pos)
    s0 = unzigzag(unpack_uint64(raw, c))
    raw, pos = _read_blob(data, pos)
    sym = decode_int_matrix(raw, (t - 1, c)) if t > 1 else np.zeros((0, c), dtype=np.int64)
    return _integrate(np.concatenate([s0[None], sym], axis=0)) * step, pos
