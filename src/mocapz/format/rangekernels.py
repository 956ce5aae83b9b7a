"""numba kernels of the range decoder under the quantized Laplace model (imported only when numba is installed;
:mod:`.entropy` and the lossless codec's kernels use them).

constriction's ``RangeDecoder`` (64-bit state, 32-bit words) with ``QuantizedLaplace(-LIMIT, LIMIT)`` models at
24-bit precision, reimplemented with the same integer arithmetic and the same CDF expression: the same symbols in
one pass. The cumulatives of the symbols -15..16 under each column's scale in a scale block are kept as they are
made (the same integers) and looked up: a mostly-zero column makes two, a busy one a few more.

The encoder's side: :func:`encode_laplace` and :func:`seal` (constriction's ``RangeEncoder``, the same words), and
the scale search of :mod:`.entropy_costs` over a block's candidate scales (:func:`histogram_codes`,
:func:`block_codes`: the bits from its table, summed in NumPy's order, the same codes).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

LIMIT = (1 << 15) - 1
PRECISION = 24
OK, BAD_DATA = 0, 3  # statuses (the lossless kernels' 1 and 2 are theirs)
_U32 = np.uint64(32)
_RENORM = np.uint64(1 << 32)
_FULL = np.uint64(0xFFFFFFFFFFFFFFFF)


@njit(cache=True)
def _left(s: int, b: float, limit: int) -> int:
    """Left cumulative (out of ``2**24``) of symbol ``s`` under the leaky quantized Laplace(0, b) on
    ``[-limit, limit]``; ``s = limit + 1`` gives the total. The CDF is evaluated as the encoder's
    (``probability`` crate) is, ``0.5 exp(x / b)`` or ``1 - 0.5 exp(-x / b)``, truncated after scaling."""
    if s <= -limit:
        return 0
    if s > limit:
        return 1 << PRECISION
    x = float(s) - 0.5
    if x <= 0.0:
        c = 0.5 * math.exp(x / b)
    else:
        c = 1.0 - 0.5 * math.exp(-x / b)
    return int(float((1 << PRECISION) - 1 - 2 * limit) * c) + (s + limit)


@njit(cache=True)
def _find_symbol(q: int, b: float, limit: int) -> tuple[int, int, int]:
    """The symbol whose interval ``[left, right)`` holds quantile ``q``: a guess from the inverse CDF,
    checked against the exact CDF, else bisection."""
    p = (q - limit + 0.5) / float((1 << PRECISION) - 1 - 2 * limit)
    p = min(max(p, 1e-300), 1.0 - 1e-16)
    x = b * math.log(2.0 * p) if p <= 0.5 else -b * math.log(2.0 - 2.0 * p)
    s = int(math.floor(min(max(x, -limit), limit) + 0.5))
    left = _left(s, b, limit)
    if left <= q:
        right = _left(s + 1, b, limit)
        if right > q:
            return s, left, right
        nxt = _left(s + 2, b, limit)
        if nxt > q:
            return s + 1, right, nxt
        # every symbol adds at least 1 to the cumulative: the symbol is at most g (exactly g where the CDF is flat,
        # in the tails the leaky floor holds alone)
        g = min(s + 2 + (q - nxt), limit)
        lo, hi = s + 2, g + 1
        at = _left(g, b, limit)
        if at <= q:
            return g, at, _left(g + 1, b, limit)
        hi = g
    else:
        prev = _left(s - 1, b, limit)
        if prev <= q:
            return s - 1, prev, left
        g = max(s - 1 - (prev - q), -limit)  # likewise: the symbol is at least g
        lo, hi = g, s - 1
        after = _left(g + 1, b, limit)
        if after > q:
            return g, _left(g, b, limit), after
        lo = g + 1
    while hi - lo > 1:  # left(lo) <= q < left(hi)
        mid = (lo + hi) // 2
        if _left(mid, b, limit) <= q:
            lo = mid
        else:
            hi = mid
    return lo, _left(lo, b, limit), _left(lo + 1, b, limit)


@njit(cache=True)
def start(words: np.ndarray) -> tuple[np.uint64, int]:
    """The decoder's first point and the words read: ``(point, read)``."""
    point = np.uint64(0)
    read = 0
    while read < 2 and read < words.size:
        point = (point << _U32) | np.uint64(words[read])
        read += 1
    if read == 1:
        point = point << _U32
    return point, read


@njit(cache=True)
def _advance(words: np.ndarray, point: np.uint64, lower: np.uint64, rng: np.uint64, read: int, width: np.uint64,
             left: int, right: int) -> tuple[np.uint64, np.uint64, np.uint64, int]:
    """The decoder's state after a symbol of interval ``[left, right)`` (renormalised by a word when the range
    falls under 2**32): ``(point, lower, range, read)``."""
    lower = lower + width * np.uint64(left)
    rng = width * np.uint64(right - left)
    if rng < _RENORM:
        lower = lower << _U32
        rng = rng << _U32
        point = point << _U32
        if read < words.size:
            point = point | np.uint64(words[read])
        read += 1
    return point, lower, rng, read


@njit(cache=True)
def step(words: np.ndarray, point: np.uint64, lower: np.uint64, rng: np.uint64, read: int,
         b: float, limit: int) -> tuple[int, np.uint64, np.uint64, np.uint64, int, bool]:
    """Decode one symbol under the Laplace scale ``b`` on ``[-limit, limit]``: ``(symbol, point, lower, range,
    read, ok)`` (not ``ok``: the point lies outside the range, corrupt data)."""
    width = rng >> np.uint64(PRECISION)
    q = (point - lower) // width
    if q >= np.uint64(1 << PRECISION):
        return 0, point, lower, rng, read, False
    s, left, right = _find_symbol(np.int64(q), b, limit)
    point, lower, rng, read = _advance(words, point, lower, rng, read, width, left, right)
    return s, point, lower, rng, read, True


@njit(cache=True)
def begin(words: np.ndarray) -> np.ndarray:
    """A decoder's state at the start of the stream ``words``: ``[point, lower, range, words read]`` uint64."""
    point, read = start(words)
    return np.array([point, np.uint64(0), _FULL, np.uint64(read)], dtype=np.uint64)


TABLE = 15  # symbols -TABLE .. TABLE + 1: their cumulatives kept per column and scale block (the rest: computed)
TOP = 2 * TABLE + 1  # the last kept cumulative's index (symbol TABLE + 1)


@njit(cache=True, nogil=True)
def decode_laplace(words: np.ndarray, state: np.ndarray, scale: np.ndarray, row0: int, block: int, limit: int,
                   out: np.ndarray) -> int:
    """Fill ``out`` ``(rows, cols)`` int64 with the next symbols of the stream ``words`` (uint32), row by row,
    each under the Laplace scale ``scale[(row0 + row) // block, col]`` on ``[-limit, limit]``, from and to the
    decoder's ``state`` (:func:`begin`); returns :data:`OK` or :data:`BAD_DATA`."""
    rows, cols = out.shape
    point, lower, rng, read = state[0], state[1], state[2], np.int64(state[3])
    # lefts[c, i]: the left cumulative of symbol i - TABLE under column c's scale in the block: _left's integer, made
    # the first time a symbol's search asks for it (-1: not made yet; a column of zeros makes two). Written out here,
    # not in a helper taking the array (a call per symbol passing an array costs more than the search)
    lefts = np.full((cols, TOP + 1), -1, dtype=np.int64)
    nwords = words.size
    tabled = (row0 // block) if rows else -1  # the block whose cumulatives ``lefts`` holds
    for t in range(rows):
        blk = (row0 + t) // block
        if blk != tabled:
            lefts[:, :] = -1
            tabled = blk
        for c in range(cols):
            b = scale[blk, c]
            width = rng >> np.uint64(PRECISION)
            q = (point - lower) // width
            if q >= np.uint64(1 << PRECISION):
                return BAD_DATA
            qi = np.int64(q)
            zero = lefts[c, TABLE]
            if zero < 0:
                zero = lefts[c, TABLE] = _left(0, b, limit)
            one = lefts[c, TABLE + 1]
            if one < 0:
                one = lefts[c, TABLE + 1] = _left(1, b, limit)
            lo, hi = -1, -1  # the bisection's bounds, left(lo) <= q < left(hi), or none: outside the kept symbols
            if qi < zero:
                e = lefts[c, 0]
                if e < 0:
                    e = lefts[c, 0] = _left(-TABLE, b, limit)
                if e <= qi:
                    lo, hi = 0, TABLE
            elif qi >= one:
                e = lefts[c, TOP]
                if e < 0:
                    e = lefts[c, TOP] = _left(TOP - TABLE, b, limit)
                if qi < e:
                    lo, hi = TABLE + 1, TOP
            else:
                lo, hi = TABLE, TABLE + 1
            if lo >= 0:
                while hi - lo > 1:
                    mid = (lo + hi) >> 1
                    e = lefts[c, mid]
                    if e < 0:
                        e = lefts[c, mid] = _left(mid - TABLE, b, limit)
                    if e <= qi:
                        lo = mid
                    else:
                        hi = mid
                s, left, right = lo - TABLE, lefts[c, lo], lefts[c, hi]
            else:
                s, left, right = _find_symbol(qi, b, limit)
            lower = lower + width * np.uint64(left)  # _advance, written out (see above)
            rng = width * np.uint64(right - left)
            if rng < _RENORM:
                lower = lower << _U32
                rng = rng << _U32
                point = point << _U32
                if read < nwords:
                    point = point | np.uint64(words[read])
                read += 1
            out[t, c] = s
    state[0], state[1], state[2], state[3] = point, lower, rng, np.uint64(read)
    return OK


# ---------------------------------------------------------------- encoder
_WORD = np.uint64(0xFFFFFFFF)


@njit(cache=True, nogil=True)
def encode_laplace(values: np.ndarray, scale: np.ndarray, row0: int, block: int, limit: int, state: np.ndarray,
                   out: np.ndarray) -> int:
    """constriction's ``RangeEncoder.encode`` of ``values`` ``(rows, cols)`` int64, row by row, each clipped to
    ``[-limit, limit]`` and coded under the quantized Laplace scale ``scale[(row0 + row) // block, col]``, from and to
    the encoder's ``state`` ``[lower, range, words held back, the first of them]`` uint64 (``[0, 2**64 - 1, 0, 0]``
    at the start): its words into ``out`` (room for ``rows * cols`` plus the words held back, plus 1), the count
    returned. A carry can still reach words held back (an inverted situation: the interval straddles a word
    boundary): they are written once it is resolved, here or by :func:`seal`."""
    rows, cols = values.shape
    lower, rng, held, first = state[0], state[1], np.int64(state[2]), state[3]
    n = 0
    for t in range(rows):
        blk = (row0 + t) // block
        for c in range(cols):
            s = min(max(values[t, c], -limit), limit)
            b = scale[blk, c]
            left = _left(s, b, limit)
            width = rng >> np.uint64(PRECISION)
            rng = width * np.uint64(_left(s + 1, b, limit) - left)
            new_lower = lower + width * np.uint64(left)  # wrapping
            if held and new_lower + rng > new_lower:  # back to a normal situation: the held words written
                n = _release(out, n, held, first, new_lower < lower)
                held = 0
            lower = new_lower
            if rng < _RENORM:
                rng = rng << _U32
                word = lower >> _U32
                lower = lower << _U32
                if held:
                    held += 1
                elif lower + rng > lower:
                    out[n] = np.uint32(word)
                    n += 1
                else:  # an inverted situation: the word waits for the carry
                    held, first = 1, word
    state[0], state[1], state[2], state[3] = lower, rng, np.uint64(held), first
    return n


@njit(cache=True)
def _release(out: np.ndarray, n: int, held: int, first: np.uint64, carry: bool) -> int:
    """Write ``held`` words held back in an inverted situation: the first (plus the carry) and the others (all
    ones, or all zeros after a carry)."""
    out[n] = np.uint32((first + np.uint64(1)) & _WORD) if carry else np.uint32(first)
    fill = np.uint32(0) if carry else np.uint32(0xFFFFFFFF)
    for i in range(1, held):
        out[n + i] = fill
    return n + held


@njit(cache=True)
def seal(state: np.ndarray, out: np.ndarray) -> int:
    """The words that end a stream in ``state`` (constriction's ``seal``: the words held back, then a point of the
    interval, then a zero word where the interval's upper end shares the point's word) into ``out`` (room for the
    words held back plus 2); their count (0 for a stream without a symbol)."""
    lower, rng, held, first = state[0], state[1], np.int64(state[2]), state[3]
    if rng == _FULL:
        return 0
    point = lower + (_RENORM - np.uint64(1))  # wrapping
    n = _release(out, 0, held, first, point < lower) if held else 0
    word = point >> _U32
    out[n] = np.uint32(word)
    n += 1
    if ((lower + rng) >> _U32) == word:
        out[n] = np.uint32(0)
        n += 1
    return n


@njit(cache=True, nogil=True)
def histogram_codes(values: np.ndarray, block: int, codes: np.ndarray, table: np.ndarray, small: np.ndarray,
                    out: np.ndarray) -> None:
    """:func:`~.entropy_costs.scale_codes`' choice for the whole blocks ``small`` marks (``(blocks,)``, the blocks
    of ``block`` rows whose absolute values are all below ``table``'s width): per block and column of ``values``
    ``(rows, columns)`` int64, the candidate of ``codes`` ``(blocks, candidates, columns)`` (whole numbers) whose
    bits from the table ``(256, values)`` weighted by the block's histogram add up the least (the first of the
    least), into ``out`` ``(blocks, columns)``. The products and their sums are NumPy's of that path, value by
    value in the same order: the same codes."""
    rows, cols = values.shape
    counts = np.zeros((table.shape[1], cols))
    top = np.zeros(cols, dtype=np.int64)
    for b in range(small.size):
        if not small[b]:
            continue
        counts[:, :] = 0.0
        top[:] = 0
        for r in range(b * block, (b + 1) * block):
            for c in range(cols):
                a = abs(values[r, c])
                counts[a, c] += 1.0
                if a > top[c]:
                    top[c] = a
        for c in range(cols):
            best = np.inf
            pick = 0
            for k in range(codes.shape[1]):
                code = int(codes[b, k, c])
                total = 0.0
                for a in range(top[c] + 1):  # values beyond the column's largest count zero times: exact no-ops
                    total += table[code, a] * counts[a, c]
                if total < best:
                    best = total
                    pick = k
            out[b, c] = int(codes[b, pick, c])


@njit(cache=True, nogil=True)
def block_codes(values: np.ndarray, codes: np.ndarray, table: np.ndarray, big_r: np.ndarray, big_c: np.ndarray,
                big_bits: np.ndarray, out: np.ndarray) -> None:
    """:func:`~.entropy_costs.code_bits`' choice for one block ``values`` ``(rows, columns)`` int64 holding values
    beyond the table: per column, the candidate of ``codes`` ``(candidates, columns)`` whose bits summed down the
    rows cost the least (the first of the least), into ``out`` ``(columns,)``; each value's bits from the table
    ``(256, values)``, but at ``(big_r[i], big_c[i])`` (the values beyond it) ``big_bits[:, i]``, computed by NumPy
    (``(candidates, count)``). Summed in NumPy's order, row after row: the same codes."""
    rows, cols = values.shape
    cands = codes.shape[0]
    slot = np.full((rows, cols), -1, dtype=np.int64)
    for i in range(big_r.size):
        slot[big_r[i], big_c[i]] = i
    total = np.empty(cands)
    rows_of = np.empty(cands, dtype=np.int64)
    local = np.empty((table.shape[1], cands))  # the column's candidates' table rows, value by value (cached)
    for c in range(cols):
        for k in range(cands):
            total[k] = 0.0
            rows_of[k] = int(codes[k, c])
            for a in range(table.shape[1]):
                local[a, k] = table[rows_of[k], a]
        for r in range(rows):  # every candidate's sum one row further: independent additions, each in row order
            i = slot[r, c]
            if i >= 0:
                for k in range(cands):
                    total[k] += big_bits[k, i]
            else:
                a = abs(values[r, c])
                for k in range(cands):
                    total[k] += local[a, k]
        best = np.inf
        pick = 0
        for k in range(cands):
            if total[k] < best:
                best = total[k]
                pick = k
        out[c] = rows_of[pick]
