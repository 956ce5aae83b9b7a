"""Range coding of an integer matrix whose columns come in groups that share their Laplace scales.

:func:`mocapz.format.entropy.encode_int_matrix` gives every column a scale of its own per block of
:data:`~mocapz.format.entropy.BLOCK` rows, in quarter octaves: a few bits each, which a short matrix (a clip of a
second or two, a block of a stream: a lifting level of 8 to 64 rows) pays on every column and level, up to a
third of its bytes. Here the columns of one group (the caller's: a joint's channels, a marker's x, y and z, whose
magnitudes go together) share one scale per block, in half octaves: a third of the codes, a bit less each, for a
little more on the values.

:func:`encode_int_matrix` writes the smaller of that stream and :mod:`~mocapz.format.entropy`'s; its
:func:`decode_int_matrix` reads both. The stream (``CODER_RANGE_SHARED``): the coder id, the shape (uvarints),
the pick of the scale codes' difference model (an index into :data:`~mocapz.format.entropy.DELTA_SCALES`), then
the escapes and the range-coded body (each after its uvarint length), the body holding the scale codes
``(blocks, groups)`` as differences (block, then group order, from :data:`HALF_BIAS`), then the values row by
row. The groups are not stored: the decoder is given the same ``groups`` ``(columns,)`` as the encoder (any
integer labels; a scale per distinct label, in sorted order).
"""

from __future__ import annotations

import numpy as np

from mocapz.errors import FormatError
from mocapz.format import entropy as E

CODER_RANGE_SHARED = 5  # the coder id (after mocapz.format.entropy's 1 to 4)
HALF_BIAS = 16  # s = 2 ** ((q - HALF_BIAS) / 2), q in 0 .. HALF_TOP (the quarter-octave codes' range)
HALF_TOP = 63
OFFSETS = range(-2, 7)  # the codes tried around the one of the group's mean absolute value (sparse groups: wider)


def dense(groups: np.ndarray, cols: int) -> tuple[np.ndarray, int]:
    """The groups ``(cols,)`` as labels ``0 .. n - 1`` (sorted order) and their number ``n`` (ValueError if
    ``groups`` does not label ``cols`` columns)."""
    g = np.asarray(groups).reshape(-1)
    if g.size != cols:
        raise ValueError(f"{g.size} column groups for {cols} columns")
    labels, inverse = np.unique(g, return_inverse=True)
    return inverse.astype(np.int64), int(labels.size)


def _codes(values: np.ndarray, gid: np.ndarray, n: int) -> np.ndarray:
    """The half-octave scale codes ``(blocks, n)`` under which each block's groups cost the fewest bits."""
    rows, cols = values.shape
    nb = max(1, -(-rows // E.BLOCK))
    counts = np.bincount(gid, minlength=n).astype(np.float64)
    q = np.zeros((nb, n), dtype=np.int64)
    for b in range(nb):
        blk = np.abs(values[b * E.BLOCK:(b + 1) * E.BLOCK]).astype(np.float64)
        mean = np.bincount(gid, weights=blk.mean(axis=0), minlength=n) / np.maximum(counts, 1)
        guess = np.round(np.log2(np.maximum(mean, 2.0 ** -6)) * 2) + HALF_BIAS
        codes = np.clip(guess[None, :] + np.asarray(OFFSETS, dtype=np.float64)[:, None], 0, HALF_TOP)  # (offsets, n)
        per_col = E.code_bits(E._histogram(blk), codes[:, gid], 2, HALF_BIAS)
        cost = np.stack([np.bincount(gid, weights=c, minlength=n) for c in per_col])
        q[b] = codes[np.argmin(cost, axis=0), np.arange(n)]  # the first of the cheapest, in OFFSETS' order
    return q


def encode(v: np.ndarray, groups: np.ndarray) -> bytes:
    """The ``CODER_RANGE_SHARED`` stream of ``v`` ``(rows, columns)`` int64 (not empty) with scales shared by the
    columns of each group of ``groups`` ``(columns,)``."""
    rows, cols = v.shape
    gid, n = dense(groups, cols)
    q = _codes(v, gid, n)
    diffs = np.abs(np.diff(q.ravel(), prepend=HALF_BIAS))[:, None].astype(np.float64)
    pick = int(np.argmin([E._laplace_bits(diffs, None, np.array([d]))[0] for d in E.DELTA_SCALES]))
    enc = E.range_writer(v.size)
    E._encode_scale_codes(enc, q - (HALF_BIAS - E.QUARTER_BIAS), pick)  # differences from HALF_BIAS
    esc = E._encode_values(enc, v, _scales(q, gid))
    body = enc.body()
    return bytes([CODER_RANGE_SHARED]) + E.write_uvarint(rows) + E.write_uvarint(cols) + bytes([pick]) \
        + E.write_uvarint(len(esc)) + esc + E.write_uvarint(len(body)) + body


def _scales(q: np.ndarray, gid: np.ndarray) -> np.ndarray:
    """The Laplace scales ``(blocks, columns)`` of the group codes ``q`` ``(blocks, groups)``."""
    return 2.0 ** ((q[:, gid].astype(np.float64) - HALF_BIAS) / 2)


def encode_int_matrix(values: np.ndarray, groups: np.ndarray) -> bytes:
    """The smaller of :func:`mocapz.format.entropy.encode_int_matrix`'s stream of ``values`` ``(rows, columns)``
    and :func:`encode`'s with the columns' ``groups`` ``(columns,)``."""
    v = np.asarray(values, dtype=np.int64)
    best = E.encode_int_matrix(v)
    if E.HAVE_CONSTRICTION and v.ndim == 2 and v.size:
        shared = encode(v, groups)
        best = shared if len(shared) < len(best) else best
    return best


def decode_int_matrix(data: bytes, shape: tuple[int, int], groups: np.ndarray) -> np.ndarray:
    """Inverse of :func:`encode_int_matrix`: the ``shape`` ``(rows, columns)`` int64 matrix, given the encoder's
    ``groups`` (a stream claiming another shape is a FormatError before anything is decoded)."""
    buf = memoryview(data)
    if not len(buf) or buf[0] != CODER_RANGE_SHARED:
        return E.decode_int_matrix(data, shape)
    rows, pos = E.read_uvarint(buf, 1)
    cols, pos = E.read_uvarint(buf, pos)
    if (rows, cols) != tuple(shape):
        raise FormatError(None, f"corrupted integer stream (shape {(rows, cols)} where {tuple(shape)} is expected)")
    if not E.HAVE_CONSTRICTION:
        raise FormatError(None, "this stream was written by the range coder; install 'constriction'")
    if rows * cols == 0:
        return np.zeros((rows, cols), dtype=np.int64)
    return decode(buf, pos, rows, cols, groups)


def decode(buf: memoryview, pos: int, rows: int, cols: int, groups: np.ndarray) -> np.ndarray:
    """The values of a ``CODER_RANGE_SHARED`` stream whose shape has been read (``pos``: just after it), with the
    encoder's ``groups``."""
    try:
        gid, n = dense(groups, cols)
    except ValueError as exc:
        raise FormatError(None, f"corrupted integer stream ({exc})") from None
    if pos >= len(buf) or buf[pos] >= len(E.DELTA_SCALES):
        raise FormatError(None, "corrupted integer stream (scale model)")
    pick = buf[pos]
    esc_bytes, body = E._escapes_and_body(buf, pos + 1)
    nb = max(1, -(-rows // E.BLOCK))
    try:
        dec = E.range_decoder(body, rows * cols)
        q = E._decode_scale_codes(dec, pick, nb, n) + (HALF_BIAS - E.QUARTER_BIAS)
        if q.size and (q.min() < 0 or q.max() > HALF_TOP):
            raise FormatError(None, "corrupted integer stream (scales)")
        sym, marks = E._decode_values(dec, _scales(q, gid), rows, cols)
    except FormatError:
        raise
    except Exception as exc:  # constriction raises plain exceptions on corrupt input
        raise FormatError(None, f"corrupted entropy-coded data ({exc})") from None
    return E._unescape(sym, esc_bytes, marks)
