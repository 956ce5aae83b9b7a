"""numba kernels of :mod:`.fast` (imported only when numba is installed; see there)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mocapz.codecs.lossless.status import BAD_DATA, BAD_ESCAPES, BAD_LOW_BITS, OK
from mocapz.format.rangekernels import LIMIT, start, step

FRAC, RATE, HIGH_BITS = 4, 2, 7
MAX_STATE = 1 << 50
MIN_SCALE = 0.04


@njit(cache=True)
def _model(st: int) -> tuple[int, float]:
    """Low-bit count and Laplace scale of a running state (as ``coding._row_model``)."""
    k = math.frexp(float(st >> FRAC))[1] - HIGH_BITS
    if k < 0:
        k = 0
    scale = float(st) / float(1 << FRAC) / float(1 << k)
    return k, max(scale, MIN_SCALE)


@njit(cache=True)
def _next_state(st: int, v: int) -> int:
    a = abs(v)
    target = min(a, MAX_STATE >> FRAC) << FRAC
    return st + ((target - st) >> RATE)


@njit(cache=True, nogil=True)
def decode_residual_rows(words: np.ndarray, mask: np.ndarray, state: np.ndarray, escapes: np.ndarray,
                          bits: np.ndarray, out: np.ndarray) -> int:
    rows, cols = mask.shape
    point, read = start(words)
    lower = np.uint64(0)
    rng = np.uint64(0xFFFFFFFFFFFFFFFF)
    at_esc = 0
    at_bit = 0
    for t in range(rows):
        for c in range(cols):
            if not mask[t, c]:
                continue
            st = state[c]
            k, b = _model(st)
            s, point, lower, rng, read, ok = step(words, point, lower, rng, read, b, LIMIT)
            if not ok:
                return BAD_DATA
            high = np.int64(s)
            if abs(high) >= LIMIT:
                if at_esc >= escapes.size:
                    return BAD_ESCAPES
                high = escapes[at_esc]
                at_esc += 1
            if at_bit + k > bits.size:
                return BAD_LOW_BITS
            low = np.int64(0)
            for j in range(k):
                low |= np.int64(bits[at_bit + j]) << j
            at_bit += k
            v = (high << k) + low
            out[t, c] = v
            state[c] = _next_state(st, v)
    return OK


@njit(cache=True, nogil=True)
def row_models(r: np.ndarray, mask: np.ndarray, state: np.ndarray, ks: np.ndarray, scales: np.ndarray) -> None:
    rows, cols = r.shape
    for t in range(rows):
        for c in range(cols):
            st = state[c]
            k, b = _model(st)
            ks[t, c] = k
            scales[t, c] = b
            if mask[t, c]:
                state[c] = _next_state(st, r[t, c])


@njit(cache=True, nogil=True)
def undo_prediction(residual: np.ndarray, order: np.ndarray, npred: np.ndarray, pidx: np.ndarray,
                    pcoef: np.ndarray, active: np.ndarray, d1: np.ndarray, x: np.ndarray) -> None:
    """Frames 1.. of the active columns of ``x`` ``(frames, cols)`` (every row holding the first frame) from
    the first differences ``d1`` and the residuals ``(frames - 2, len(order))``, in place (wrapping int64)."""
    rows, n = residual.shape
    d2 = np.zeros(x.shape[1], dtype=np.int64)
    slope = d1.copy()
    for a in range(active.size):
        x[1, active[a]] += slope[a]
    for t in range(rows):
        for i in range(n):
            cross = np.int64(0)
            if npred[i]:
                acc = np.int64(0)
                for j in range(npred[i]):
                    acc += d2[pidx[i, j]] * pcoef[i, j]
                cross = (acc + np.int64(1 << 7)) >> 8
            d2[order[i]] = residual[t, i] + cross
        for a in range(active.size):
            c = active[a]
            slope[a] += d2[c]
            x[t + 2, c] = x[t + 1, c] + slope[a]


@njit(cache=True, nogil=True)
def pack_low(low: np.ndarray, k: np.ndarray) -> np.ndarray:
    """``k[i]`` low bits of each ``low[i]``, least significant first, packed most significant bit first
    (``np.packbits`` order), as :func:`~.coding._pack_low`."""
    total = 0
    for i in range(k.size):
        total += k[i]
    out = np.zeros((total + 7) // 8, dtype=np.uint8)
    pos = 0
    for i in range(k.size):
        v = low[i]
        for j in range(k[i]):
            if (v >> np.uint64(j)) & np.uint64(1):
                out[pos >> 3] |= np.uint8(0x80 >> (pos & 7))
            pos += 1
    return out
