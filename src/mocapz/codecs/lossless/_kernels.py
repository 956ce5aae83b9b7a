"""numba kernels of :mod:`.fast` (imported only when numba is installed; see there)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

LIMIT = (1 << 15) - 1
PRECISION = 24
FREE_WEIGHT = float((1 << PRECISION) - 1 - 2 * LIMIT)  # the leaky quantizer's weight of the continuous CDF
FRAC, RATE, HIGH_BITS = 4, 2, 7
MAX_STATE = 1 << 50
MIN_SCALE = 0.04
OK, BAD_ESCAPES, BAD_LOW_BITS, BAD_DATA = 0, 1, 2, 3


@njit(cache=True)
def _left(s: int, b: float) -> int:
    """Left cumulative (out of ``2**24``) of symbol ``s`` under the leaky quantized Laplace(0, b) on
    ``[-LIMIT, LIMIT]``; ``s = LIMIT + 1`` gives the total. The CDF is evaluated as the encoder's
    (``probability`` crate) is, ``0.5 exp(x / b)`` or ``1 - 0.5 exp(-x / b)``, truncated after scaling."""
    if s <= -LIMIT:
        return 0
    if s > LIMIT:
        return 1 << PRECISION
    x = float(s) - 0.5
    if x <= 0.0:
        c = 0.5 * math.exp(x / b)
    else:
        c = 1.0 - 0.5 * math.exp(-x / b)
    return int(FREE_WEIGHT * c) + (s + LIMIT)


@njit(cache=True)
def _find_symbol(q: int, b: float) -> tuple[int, int, int]:
    """The symbol whose interval ``[left, right)`` holds quantile ``q``: a guess from the inverse CDF,
    checked against the exact CDF, else bisection."""
    p = (q - LIMIT + 0.5) / FREE_WEIGHT
    p = min(max(p, 1e-300), 1.0 - 1e-16)
    x = b * math.log(2.0 * p) if p <= 0.5 else -b * math.log(2.0 - 2.0 * p)
    s = int(math.floor(min(max(x, -LIMIT), LIMIT) + 0.5))
    left = _left(s, b)
    if left <= q:
        right = _left(s + 1, b)
        if right > q:
            return s, left, right
        nxt = _left(s + 2, b)
        if nxt > q:
            return s + 1, right, nxt
        lo, hi = s + 2, LIMIT + 1
    else:
        prev = _left(s - 1, b)
        if prev <= q:
            return s - 1, prev, left
        lo, hi = -LIMIT, s - 1
    while hi - lo > 1:  # left(lo) <= q < left(hi)
        mid = (lo + hi) // 2
        if _left(mid, b) <= q:
            lo = mid
        else:
            hi = mid
    return lo, _left(lo, b), _left(lo + 1, b)


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
    n_words = words.size
    u32 = np.uint64(32)
    point = np.uint64(0)
    read = 0
    while read < 2 and read < n_words:
        point = (point << u32) | np.uint64(words[read])
        read += 1
    if read == 1:
        point = point << u32
    lower = np.uint64(0)
    rng = np.uint64(0xFFFFFFFFFFFFFFFF)
    renorm = np.uint64(1 << 32)
    at_esc = 0
    at_bit = 0
    for t in range(rows):
        for c in range(cols):
            if not mask[t, c]:
                continue
            st = state[c]
            k, b = _model(st)
            step = rng >> np.uint64(PRECISION)
            q = (point - lower) // step
            if q >= np.uint64(1 << PRECISION):
                return BAD_DATA
            s, left, right = _find_symbol(np.int64(q), b)
            lower = lower + step * np.uint64(left)
            rng = step * np.uint64(right - left)
            if rng < renorm:
                lower = lower << u32
                rng = rng << u32
                point = point << u32
                if read < n_words:
                    point = point | np.uint64(words[read])
                read += 1
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
