"""Entropy coding of the lossless codec's residuals, exceptions and sign lists.

Residuals (:func:`encode_residuals`): only the entries a mask marks as coded (marker gaps cost nothing);
per block of rows and column, a Laplace scale byte and a count of low bits ``k``: the high part
``r >> k`` is range coded (constriction, quantized Laplace; beyond the alphabet escaped and stored
exactly), the ``k`` low bits are stored raw. Noisy high-precision data (1e-5 mm marker text) thus never
leaves the coder's alphabet. Without constriction the entries go through zstd byte planes instead.

Index lists (:func:`encode_indices`): sorted positions as zstd-packed gaps or runs.
"""

from __future__ import annotations

import numpy as np

from mocapz.codecs.lossless import fast
from mocapz.codecs.lossless.status import BAD_ESCAPES, BAD_LOW_BITS
from mocapz.errors import FormatError
from mocapz.format.entropy import (
    HAVE_CONSTRICTION,
    LIMIT,
    pack_uint64,
    read_uvarint,
    unpack_uint64,
    unzigzag,
    write_uvarint,
    zigzag,
)
from mocapz.format.planes import LEVEL

if HAVE_CONSTRICTION:
    import constriction

CODER_RANGE, CODER_ZSTD = 1, 2
FRAC = 4  # the scale state is 16 x the running mean |residual| (integer)
RATE = 2  # the state moves a quarter of the way to each new |residual|
HIGH_BITS = 7  # low bits are split off while the running mean exceeds 2**HIGH_BITS
MAX_STATE = 1 << 50
MIN_SCALE = 0.04
# zstd's level of the index lists (a BVH's "-0.000000" values, the exact values' positions): on the 42 shared
# files 12 codes them in 0.013 % more bytes than 19 in all (at most +0.14 %, a pymo BVH), and the whole lossless
# encode of the CMU clips runs about a fifth faster (a fifth of it was level 19 on these lists)
INDEX_LEVEL = 12


def _initial_state(r: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Per column: a one-byte code of the mean |residual| over the first coded rows."""
    head = np.abs(r[:16]).astype(np.float64) * mask[:16]
    mean = head.sum(axis=0) / np.maximum(mask[:16].sum(axis=0), 1)
    return np.clip(np.round(np.log2(mean + 1.0) * 4), 0, 200).astype(np.uint8)


def _state_of(code: np.ndarray) -> np.ndarray:
    return np.minimum(np.round((2.0 ** (code.astype(np.float64) / 4) - 1.0) * (1 << FRAC)), MAX_STATE).astype(np.int64)


def _row_model(state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Low-bit counts and Laplace scales of a row's high parts, from the running states (exact arithmetic)."""
    mean = (state >> FRAC).astype(np.float64)
    k = np.maximum(np.frexp(mean)[1] - HIGH_BITS, 0).astype(np.int64)
    scale = np.maximum(state.astype(np.float64) / float(1 << FRAC) / np.exp2(k), MIN_SCALE)
    return k, scale


def _update(state: np.ndarray, r: np.ndarray) -> np.ndarray:
    target = np.minimum(np.abs(r), MAX_STATE >> FRAC) << FRAC
    return state + ((target - state) >> RATE)


def _split_low(values: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    high = values >> k
    return high, (values - (high << k)).astype(np.uint64)


def _pack_low(low: np.ndarray, k: np.ndarray) -> bytes:
    """``k[i]`` low bits of each ``low[i]`` (uint64), least significant first, packed."""
    kern = fast.kernels()
    if kern is not None:
        packed = kern.pack_low(np.ascontiguousarray(low, dtype=np.uint64), np.ascontiguousarray(k, dtype=np.int64))
        return packed.tobytes()
    some = k > 0
    low, k = low[some], k[some]
    kmax = int(k.max(initial=0))
    if kmax == 0:
        return b""
    bit = np.arange(kmax, dtype=np.uint64)
    bits = ((low[:, None] >> bit) & np.uint64(1)).astype(np.uint8)
    return np.packbits(bits[bit[None, :] < k[:, None].astype(np.uint64)]).tobytes()


def _read_low(bits: np.ndarray, at: int, k: np.ndarray) -> tuple[np.ndarray, int]:
    kmax = int(k.max(initial=0))
    total = int(k.sum())
    if at + total > bits.size:
        raise FormatError(None, "corrupted residual stream (low bits)")
    if kmax == 0:
        return np.zeros(k.size, dtype=np.int64), at
    bit = np.arange(kmax, dtype=np.int64)
    grid = np.zeros((k.size, kmax), dtype=np.int64)
    grid[bit[None, :] < k[:, None]] = bits[at : at + total]
    return (grid << bit).sum(axis=1), at + total


def encode_residuals(r: np.ndarray, mask: np.ndarray) -> bytes:
    """Code the entries of ``r`` ``(rows, columns)`` int64 where ``mask`` is True, row by row; each column's
    Laplace scale follows the running mean of its last residuals."""
    rows, cols = r.shape
    shape = write_uvarint(rows) + write_uvarint(cols)
    if not HAVE_CONSTRICTION or not mask.any():
        return bytes([CODER_ZSTD]) + shape + pack_uint64(zigzag(r[mask]))
    code = _initial_state(r, mask)
    state = _state_of(code)
    ks, scales = np.zeros(r.shape, dtype=np.int64), np.zeros(r.shape)
    kern = fast.kernels(r.size)
    if kern is not None:
        kern.row_models(np.ascontiguousarray(r), np.ascontiguousarray(mask), state, ks, scales)
    else:
        for t in range(rows):
            ks[t], scales[t] = _row_model(state)
            state = np.where(mask[t], _update(state, r[t]), state)
    values, k = r[mask], ks[mask]
    high, low = _split_low(values, k)
    sym = np.clip(high, -LIMIT, LIMIT)
    escapes = high[np.abs(high) >= LIMIT]
    enc = constriction.stream.queue.RangeEncoder()
    enc.encode(sym.astype(np.int32), constriction.stream.model.QuantizedLaplace(-LIMIT, LIMIT),
               np.zeros(values.size), scales[mask])
    body = enc.get_compressed().tobytes()
    esc = pack_uint64(zigzag(escapes)) if escapes.size else b""
    lows = _pack_low(low, k)
    return (bytes([CODER_RANGE]) + shape + code.tobytes() + write_uvarint(len(esc)) + esc
            + write_uvarint(len(lows)) + lows + write_uvarint(len(body)) + body)


def residual_shape(data: bytes) -> tuple[tuple[int, int], int]:
    """The ``(rows, columns)`` a residual stream holds, and where its body starts (checked before any
    allocation: a damaged header must not make the decoder allocate for a huge clip)."""
    if len(data) < 3:
        raise FormatError(None, "truncated residual stream")
    rows, pos = read_uvarint(data, 1)
    cols, pos = read_uvarint(data, pos)
    return (rows, cols), pos


def decode_residuals(data: bytes, mask: np.ndarray) -> np.ndarray:
    """Inverse of :func:`encode_residuals`: ``(rows, columns)`` int64, zero where ``mask`` is False."""
    rows, cols = mask.shape
    shape, pos = residual_shape(data)
    if shape != (rows, cols):
        raise FormatError(None, f"corrupted residual stream (shape {shape} where {(rows, cols)} is expected)")
    out = np.zeros((rows, cols), dtype=np.int64)
    if data[0] == CODER_ZSTD:
        out[mask] = unzigzag(unpack_uint64(data[pos:], int(mask.sum())))
        return out
    if data[0] != CODER_RANGE:
        raise FormatError(None, f"unknown residual coder {data[0]}")
    if not HAVE_CONSTRICTION:
        raise FormatError(None, "this stream was written by the range coder; install 'constriction'")
    if pos + cols > len(data):
        raise FormatError(None, "truncated residual stream (scales)")
    code = np.frombuffer(data[pos : pos + cols], dtype=np.uint8)
    pos += cols
    if int(code.max(initial=0)) > 200:
        raise FormatError(None, "corrupted residual stream (initial scale)")
    parts = []
    for _ in range(3):
        size, pos = read_uvarint(data, pos)
        if pos + size > len(data):
            raise FormatError(None, "truncated residual stream")
        parts.append(data[pos : pos + size])
        pos += size
    esc_bytes, lows, body = parts
    if pos != len(data) or len(body) % 4:
        raise FormatError(None, "corrupted residual stream (length)")
    escapes = unzigzag(unpack_uint64(esc_bytes, at_most=int(mask.sum()))) if esc_bytes else np.zeros(0, np.int64)
    kern = fast.kernels(mask.size)
    if kern is not None:
        words = np.frombuffer(body, dtype="<u4").astype(np.uint32)
        bits8 = np.unpackbits(np.frombuffer(lows, dtype=np.uint8))
        status = kern.decode_residual_rows(words, np.ascontiguousarray(mask, dtype=bool), _state_of(code),
                                           np.ascontiguousarray(escapes, dtype=np.int64), bits8, out)
        if status:
            what = {BAD_ESCAPES: "escapes", BAD_LOW_BITS: "low bits"}.get(status)
            raise FormatError(None, f"corrupted residual stream ({what})" if what
                              else "corrupted entropy-coded data (invalid range-coded data)")
        return out
    bits = np.unpackbits(np.frombuffer(lows, dtype=np.uint8)).astype(np.int64)
    model = constriction.stream.model.QuantizedLaplace(-LIMIT, LIMIT)
    state = _state_of(code)
    at_bit = at_esc = 0
    try:
        dec = constriction.stream.queue.RangeDecoder(np.frombuffer(body, dtype=np.uint32).copy())
        for t in range(rows):
            m = mask[t]
            if not m.any():
                continue
            k, scale = _row_model(state[m])
            high = dec.decode(model, np.zeros(k.size), scale).astype(np.int64)
            big = np.abs(high) >= LIMIT
            if big.any():
                n = int(big.sum())
                if at_esc + n > escapes.size:
                    raise FormatError(None, "corrupted residual stream (escapes)")
                high[big] = escapes[at_esc : at_esc + n]
                at_esc += n
            low, at_bit = _read_low(bits, at_bit, k)
            row = (high << k) + low
            out[t, m] = row
            state[m] = _update(state[m], row)
    except FormatError:
        raise
    except Exception as exc:  # constriction raises plain exceptions on corrupt input
        raise FormatError(None, f"corrupted entropy-coded data ({exc})") from None
    return out


def pack_small(values: np.ndarray, level: int = LEVEL) -> bytes:
    """Non-negative integers: byte ``0`` + a byte-plane stream (zstd at ``level``), or byte ``1`` + plain
    uvarints (short lists, where a zstd frame's overhead would dominate), whichever is smaller."""
    u = np.asarray(values, dtype=np.uint64)
    planes = b"\0" + pack_uint64(u, level)
    if u.size > 64:
        return planes
    plain = b"\1" + write_uvarint(u.size) + b"".join(write_uvarint(int(v)) for v in u.tolist())
    return plain if len(plain) < len(planes) else planes


def unpack_small(data: bytes, count: int | None = None, at_most: int = 1 << 31) -> np.ndarray:
    """Inverse of :func:`pack_small` (``count``: the number expected, if known)."""
    if not data or data[0] > 1:
        raise FormatError(None, "corrupted integer list")
    if data[0] == 0:
        return unpack_uint64(data[1:], count, at_most=at_most)
    n, pos = read_uvarint(data, 1)
    if (count is not None and n != count) or n > min(at_most, len(data)):
        raise FormatError(None, "corrupted integer list (count)")
    out = []
    for _ in range(n):
        v, pos = read_uvarint(data, pos)
        out.append(v)
    if pos != len(data):
        raise FormatError(None, "corrupted integer list (length)")
    return np.asarray(out, dtype=np.uint64)


def encode_indices(idx: np.ndarray) -> bytes:
    """Sorted distinct non-negative positions: a format byte, then (:func:`pack_small`, zstd at
    :data:`INDEX_LEVEL`) the gaps (0: ``p[i] - p[i-1] - 1``) or the runs (1: gap before each run, run length -
    1), whichever is smaller."""
    idx = np.asarray(idx, dtype=np.int64)
    gaps = np.diff(idx, prepend=-1) - 1
    plain = b"\0" + pack_small(gaps.astype(np.uint64), INDEX_LEVEL)
    if not idx.size:
        return plain
    breaks = np.flatnonzero(np.diff(idx) != 1) + 1
    starts = idx[np.concatenate([[0], breaks])]
    ends = idx[np.concatenate([breaks - 1, [idx.size - 1]])]
    run_gaps = starts - np.concatenate([[-1], ends[:-1]]) - 1
    runs = b"\1" + pack_small(np.stack([run_gaps, ends - starts], axis=1).ravel().astype(np.uint64), INDEX_LEVEL)
    return runs if len(runs) < len(plain) else plain


def decode_indices(data: bytes, limit: int) -> np.ndarray:
    """Inverse of :func:`encode_indices`; every position must be under ``limit``."""
    if not data or data[0] > 1:
        raise FormatError(None, "corrupted index list")
    values = unpack_small(data[1:], at_most=2 * limit)
    if values.size and int(values.max()) >= limit:
        raise FormatError(None, "corrupted index list")
    if data[0] == 0:
        gaps, lengths = values.astype(np.int64), np.ones(values.size, dtype=np.int64)
    elif values.size % 2:
        raise FormatError(None, "corrupted index list")
    else:
        gaps, lengths = values[0::2].astype(np.int64), values[1::2].astype(np.int64) + 1
    ends = np.cumsum(gaps + lengths) - 1
    if ends.size and int(ends[-1]) >= limit:
        raise FormatError(None, "corrupted index list (position out of range)")
    starts = ends - lengths + 1
    offsets = np.arange(int(lengths.sum())) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return np.repeat(starts, lengths) + offsets
