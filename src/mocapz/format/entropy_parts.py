"""Range coding of a few short integer matrices (the parts of one lifting: its knots, each level's details) in a
single stream, their Laplace scales shared by column groups.

A clip of a second (a stream's block) has lifting parts of 1 to 64 rows. Coded each as a stream of its own
(:mod:`mocapz.format.entropy_shared`), every part pays its coder's id, its shape, its scale model's pick, two
lengths, the range coder's last word and a chain of scale codes starting afresh: about 30 bytes a part, six
parts a block. Here the parts go one after the other into one range-coded body: one pick, one escape list, one
flush, and the scale codes of every part coded together: the first part's as a chain of differences (block of
:data:`~mocapz.format.entropy.BLOCK` rows after block, group after group, from
:data:`~mocapz.format.entropy_shared.HALF_BIAS`), every later part's each as its difference from the same
group's code in the last block of the part before (a lifting's levels: a joint's scale follows its scale one
level up more closely than the next joint's; 12-15 % fewer scale bytes on the blocks of CMU streams).

Bytes: the pick (an index into :data:`~mocapz.format.entropy.DELTA_SCALES`; plus :data:`PER_COLUMN` where every
column has scales of its own instead of its group's), uvarint length + the escapes (a
byte-plane stream of the zig-zagged escaped values of every part, in order; none: length 0), uvarint length +
the body (the scale codes, then each part's values row by row). The parts' shapes and the columns' groups are
not stored: the reader is given them, as the writer was.
"""

from __future__ import annotations

import numpy as np

from mocapz.errors import FormatError
from mocapz.format import entropy as E
from mocapz.format.entropy_shared import HALF_BIAS, HALF_TOP, _codes, _scales, dense

PER_COLUMN = 0x10  # flag in the first byte: every column a group of its own (the given groups not used)


def _blocks(rows: int) -> int:
    return max(1, -(-rows // E.BLOCK))


def _predicted(codes: list[np.ndarray]) -> np.ndarray:
    """The differences the scale codes ``(blocks_i, groups)`` of the parts are coded as (see the module)."""
    out = [np.diff(codes[0].ravel(), prepend=HALF_BIAS)]
    out += [(c - prev[-1:]).ravel() for prev, c in zip(codes, codes[1:], strict=False)]
    return np.concatenate(out)


def _codes_of(d: np.ndarray, nbs: list[int], n: int) -> list[np.ndarray]:
    """Inverse of :func:`_predicted`: each part's codes ``(nbs[i], n)``, range checked (FormatError)."""
    codes, at = [], 0
    for i, nb in enumerate(nbs):
        part = d[at:at + nb * n]
        at += nb * n
        c = (np.cumsum(part) + HALF_BIAS) if not i else (part.reshape(nb, n) + codes[-1][-1:]).ravel()
        if c.size and (c.min() < 0 or c.max() > HALF_TOP):
            raise FormatError(None, "corrupted integer stream (scales)")
        codes.append(c.reshape(nb, n))
    return codes


def encode(parts: list[np.ndarray], groups: np.ndarray) -> bytes:
    """The stream of ``parts`` (each ``(rows_i, columns)`` int64, the same columns, at least one row in all)
    with scales shared by the columns of each group of ``groups`` ``(columns,)``, or a scale per column where
    that is smaller (a joint's position channels, all zero, beside its rotations)."""
    shared = _encode(parts, groups, 0)
    own = _encode(parts, np.arange(parts[0].shape[1]), PER_COLUMN)
    return own if len(own) < len(shared) else shared


def _encode(parts: list[np.ndarray], groups: np.ndarray, flag: int) -> bytes:
    cols = parts[0].shape[1]
    gid, n = dense(groups, cols)
    codes: list[np.ndarray] = []
    for p in parts:  # an empty part's codes repeat the part's before (differences 0; the reader skips them)
        codes.append(_codes(p, gid, n) if len(p) else
                     codes[-1][-1:].copy() if codes else np.full((1, n), HALF_BIAS, dtype=np.int64))
    d = _predicted(codes)
    pick = int(np.argmin([E._laplace_bits(np.abs(d)[:, None].astype(np.float64), None, np.array([s]))[0]
                          for s in E.DELTA_SCALES]))
    enc = E.constriction.stream.queue.RangeEncoder()
    enc.encode(d.astype(np.int32), E._DELTA_MODEL, np.zeros(d.size), np.full(d.size, E.DELTA_SCALES[pick]))
    for p, c in zip(parts, codes, strict=True):
        if p.size:
            E._encode_values(enc, p, _scales(c, gid))
    body = enc.get_compressed().tobytes()
    stacked = np.concatenate(parts)
    esc = stacked[np.abs(stacked) >= E.LIMIT]
    esc_bytes = E.pack_uint64(E.zigzag(esc)) if esc.size else b""
    return bytes([pick | flag]) + E.write_uvarint(len(esc_bytes)) + esc_bytes + E.write_uvarint(len(body)) + body


def decode(data: bytes, rows: list[int], cols: int, groups: np.ndarray) -> list[np.ndarray]:
    """Inverse of :func:`encode`: the parts ``(rows[i], cols)`` int64, given the writer's ``groups``
    (FormatError if the bytes do not hold them)."""
    buf = memoryview(data)
    if not len(buf) or buf[0] & ~PER_COLUMN >= len(E.DELTA_SCALES):
        raise FormatError(None, "corrupted integer stream (scale model)")
    pick = buf[0] & ~PER_COLUMN
    try:
        gid, n = dense(np.arange(cols) if buf[0] & PER_COLUMN else groups, cols)
    except ValueError as exc:
        raise FormatError(None, f"corrupted integer stream ({exc})") from None
    if not E.HAVE_CONSTRICTION:
        raise FormatError(None, "this stream was written by the range coder; install 'constriction'")
    esc_bytes, body = E._escapes_and_body(buf, 1)
    if 1 + len(E.write_uvarint(len(esc_bytes))) + len(esc_bytes) + len(E.write_uvarint(len(body))) + len(body) \
            != len(buf):
        raise FormatError(None, "corrupted integer stream (trailing bytes)")
    total = sum(rows)
    nbs = [_blocks(r) for r in rows]
    try:
        dec = E.range_decoder(body, total * cols)
        total_codes = sum(nbs) * n
        d = dec.laplace(np.full((1, 1), E.DELTA_SCALES[pick]), total_codes, 1, 0, E.DELTA_LIMIT, total_codes + 1)
        codes = _codes_of(d.ravel(), nbs, n)
        out = [dec.laplace(_scales(c, gid), r, cols) if r else np.zeros((0, cols), np.int64)
               for r, c in zip(rows, codes, strict=True)]
    except FormatError:
        raise
    except Exception as exc:  # constriction raises plain exceptions on corrupt input
        raise FormatError(None, f"corrupted entropy-coded data ({exc})") from None
    stacked = np.concatenate(out) if out else np.zeros((0, cols), np.int64)
    E._unescape(stacked, esc_bytes, np.flatnonzero(np.abs(stacked.ravel()) >= E.LIMIT))
    return np.split(stacked, np.cumsum(rows)[:-1])
