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
column has scales of its own instead of its group's, plus :data:`ZEROS` with a mask of zero groups, below), uvarint
length + the escapes (a byte-plane stream of the zig-zagged escaped values of every part, in order; none: length
0), uvarint length + the body (the scale codes, then each part's values row by row). The parts' shapes and the
columns' groups are not stored: the reader is given them, as the writer was.

With :data:`ZEROS` (written where smaller), the groups whose values are all zero in a part (a joint's constant
position channels beside its rotations, a still joint in a block: half the columns of a 30-fps BVH stream's
blocks) are marked instead of coded: two bytes after the pick hold, per context (the first non-empty part's
groups; a later part's groups zero in the non-empty part before; those not zero there), 4 bits: the outcome
taken as likely (bit 3: zero) and a scale index into :data:`MASK_SCALES` (bits 0-2). The body starts with the
masks, part after part, each group a symbol on ``[-1, 1]`` under the quantized Laplace of its context's scale
(0: the likely outcome, 1: the other); then the scale codes of the groups not zero only: the first non-empty
part's as a chain of differences (block, then group order, from :data:`~mocapz.format.entropy_shared.HALF_BIAS`),
a later part's as differences from each group's code in the last block of the last part it was not zero in
(:data:`~mocapz.format.entropy_shared.HALF_BIAS` before any); then the values of those groups' columns only (the
others are zero). Empty parts have no mask and no codes. The chain of codes no longer jumps between the zero
groups' smallest code and the others' (62 % fewer scale-code bytes on the blocks of a 30-fps stream).
"""

from __future__ import annotations

import numpy as np

from mocapz.errors import FormatError
from mocapz.format import entropy as E
from mocapz.format.entropy_shared import HALF_BIAS, HALF_TOP, _codes, _scales, dense
from mocapz.format.rangewriter import RangeWriter

PER_COLUMN = 0x10  # flag in the first byte: every column a group of its own (the given groups not used)
ZEROS = 0x40  # flag in the first byte: the groups all zero in a part are masked, without codes or values
MASK_SCALES = (0.72, 0.36, 0.22, 0.14, 0.1, 0.07, 0.05, 0.035)  # a mask symbol's Laplace scales: P(0) = 1 -
# exp(-0.5 / s), 0.5 to 0.9999
_MASK_MODEL = E.constriction.stream.model.QuantizedLaplace(-1, 1) if E.HAVE_CONSTRICTION else None


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
    that is smaller (a joint's position channels, all zero, beside its rotations); with the groups all zero in a
    part masked (:data:`ZEROS`) where that is smaller still (the first of equals in that order)."""
    own_groups = np.arange(parts[0].shape[1])
    shared, own = _scale_codes(parts, groups), _scale_codes(parts, own_groups)  # each once for both layouts
    candidates = [_encode(parts, groups, 0, shared), _encode(parts, own_groups, PER_COLUMN, own)]
    if any(not p.all() for p in parts if len(p)):  # a zero somewhere: a group may be all zero in a part
        candidates += [_encode(parts, groups, ZEROS, shared), _encode(parts, own_groups, PER_COLUMN | ZEROS, own)]
    return min(candidates, key=len)


def _scale_codes(parts: list[np.ndarray], groups: np.ndarray) -> list[np.ndarray | None]:
    """Each part's half-octave scale codes ``(blocks, groups)`` under ``groups`` (None for an empty part)."""
    gid, n = dense(groups, parts[0].shape[1])
    return [_codes(p, gid, n) if len(p) else None for p in parts]


def _pick(d: np.ndarray) -> int:
    """The index into :data:`~mocapz.format.entropy.DELTA_SCALES` coding the scale codes' differences ``d`` in
    the fewest bits (the first of equals)."""
    return int(np.argmin([E._laplace_bits(np.abs(d)[:, None].astype(np.float64), None, np.array([s]))[0]
                          for s in E.DELTA_SCALES]))


def _escapes(parts: list[np.ndarray]) -> bytes:
    """The byte-plane stream of every part's escaped values (zig-zagged, in order), b"" without any."""
    stacked = np.concatenate(parts)
    esc = stacked[np.abs(stacked) >= E.LIMIT]
    return E.pack_uint64(E.zigzag(esc)) if esc.size else b""


def _encode(parts: list[np.ndarray], groups: np.ndarray, flag: int,
            scale_codes: list[np.ndarray | None] | None = None) -> bytes:
    """The stream of ``parts`` with ``flag`` (the groups given by it); ``scale_codes``: :func:`_scale_codes`
    of the same groups, when made already."""
    scale_codes = _scale_codes(parts, groups) if scale_codes is None else scale_codes
    if flag & ZEROS:
        return _encode_masked(parts, groups, flag, scale_codes)
    cols = parts[0].shape[1]
    gid, n = dense(groups, cols)
    codes: list[np.ndarray] = []
    for c in scale_codes:  # an empty part's codes repeat the part's before (differences 0; the reader skips them)
        codes.append(c if c is not None else
                     codes[-1][-1:].copy() if codes else np.full((1, n), HALF_BIAS, dtype=np.int64))
    d = _predicted(codes)
    pick = _pick(d)
    enc = E.range_writer(sum(p.size for p in parts))
    E.encode_differences(enc, d, pick)
    for p, c in zip(parts, codes, strict=True):
        if p.size:
            E._encode_values(enc, p, _scales(c, gid))
    body = enc.body()
    esc_bytes = _escapes(parts)
    return bytes([pick | flag]) + E.write_uvarint(len(esc_bytes)) + esc_bytes + E.write_uvarint(len(body)) + body


def decode(data: bytes, rows: list[int], cols: int, groups: np.ndarray) -> list[np.ndarray]:
    """Inverse of :func:`encode`: the parts ``(rows[i], cols)`` int64, given the writer's ``groups``
    (FormatError if the bytes do not hold them)."""
    buf = memoryview(data)
    if not len(buf) or buf[0] & ~(PER_COLUMN | ZEROS) >= len(E.DELTA_SCALES):
        raise FormatError(None, "corrupted integer stream (scale model)")
    pick, masked = buf[0] & ~(PER_COLUMN | ZEROS), bool(buf[0] & ZEROS)
    try:
        gid, n = dense(np.arange(cols) if buf[0] & PER_COLUMN else groups, cols)
    except ValueError as exc:
        raise FormatError(None, f"corrupted integer stream ({exc})") from None
    if not E.HAVE_CONSTRICTION:
        raise FormatError(None, "this stream was written by the range coder; install 'constriction'")
    start = 3 if masked else 1
    if len(buf) < start:
        raise FormatError(None, "truncated integer stream (mask model)")
    esc_bytes, body = E._escapes_and_body(buf, start)
    if start + len(E.write_uvarint(len(esc_bytes))) + len(esc_bytes) + len(E.write_uvarint(len(body))) \
            + len(body) != len(buf):
        raise FormatError(None, "corrupted integer stream (trailing bytes)")
    total = sum(rows)
    nbs = [_blocks(r) for r in rows]
    try:
        dec = E.range_decoder(body, total * cols)
        if masked:
            out = _decode_masked(dec, _mask_model(buf[1], buf[2]), pick, rows, cols, gid, n)
        else:
            total_codes = sum(nbs) * n
            d = dec.laplace(np.full((1, 1), E.DELTA_SCALES[pick]), total_codes, 1, 0, E.DELTA_LIMIT,
                            total_codes + 1)
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


# ---------------------------------------------------------------- masked zero groups (ZEROS)
def _zero_groups(p: np.ndarray, gid: np.ndarray, n: int) -> np.ndarray:
    """``(n,)`` True on the groups whose values in part ``p`` ``(rows, columns)`` are all zero."""
    return np.bincount(gid, weights=(p != 0).any(axis=0), minlength=n) == 0


def _contexts(zeros: list[np.ndarray]) -> list[np.ndarray]:
    """Each non-empty part's groups' mask context: 0 in the first part, then 1 where the group was zero in the
    part before, 2 where it was not."""
    return [np.zeros(z.size, np.int64) if not i else np.where(zeros[i - 1], 1, 2) for i, z in enumerate(zeros)]


def _mask_bits(likely_zero: bool, scale: float, zero: int, other: int) -> float:
    """Bits of ``zero`` zero groups and ``other`` groups not zero under one context's model."""
    p0 = -np.expm1(-0.5 / scale)
    p1 = 0.5 * (1.0 - p0)
    likely, unlikely = (zero, other) if likely_zero else (other, zero)
    return -likely * np.log2(p0) - unlikely * np.log2(p1)


def _pick_mask_model(zeros: list[np.ndarray], ctx: list[np.ndarray]) -> list[int]:
    """Per context its nibble (bit 3: zero taken as likely; bits 0-2: the index into :data:`MASK_SCALES` coding
    its groups in the fewest bits; the first of equals)."""
    z, c = np.concatenate(zeros), np.concatenate(ctx)
    out = []
    for k in range(3):
        nz, no = int(np.count_nonzero(z[c == k])), int(np.count_nonzero(~z[c == k]))
        likely = nz >= no
        bits = [_mask_bits(likely, s, nz, no) for s in MASK_SCALES]
        out.append(int(likely) << 3 | int(np.argmin(bits)))
    return out


def _mask_model(a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
    """The three contexts' ``(zero taken as likely (3,) bool, scales (3,))`` from the two mask bytes."""
    nibbles = [a & 15, a >> 4, b & 15]
    if b >> 4 or any(x & 7 >= len(MASK_SCALES) for x in nibbles):
        raise FormatError(None, "corrupted integer stream (mask model)")
    return np.array([bool(x & 8) for x in nibbles]), np.array([MASK_SCALES[x & 7] for x in nibbles])


def _encode_masked(parts: list[np.ndarray], groups: np.ndarray, flag: int,
                   scale_codes: list[np.ndarray | None]) -> bytes:
    cols = parts[0].shape[1]
    gid, n = dense(groups, cols)
    full = [p for p in parts if len(p)]
    zeros = [_zero_groups(p, gid, n) for p in full]
    ctx = _contexts(zeros)
    nibbles = _pick_mask_model(zeros, ctx)
    likely, scales = _mask_model(nibbles[0] | nibbles[1] << 4, nibbles[2])
    codes = [c for c in scale_codes if c is not None]
    last, diffs = np.full(n, HALF_BIAS, dtype=np.int64), []
    for i, (c, z) in enumerate(zip(codes, zeros, strict=True)):
        on = ~z
        diffs.append(np.diff(c[:, on].ravel(), prepend=HALF_BIAS) if not i else (c[:, on] - last[on]).ravel())
        last[on] = c[-1, on]
    d = np.concatenate(diffs) if diffs else np.zeros(0, np.int64)
    pick = _pick(d) if d.size else 0
    enc = RangeWriter()  # constriction's: the masks' model is not a Laplace
    for z, k in zip(zeros, ctx, strict=True):
        sym = (z != likely[k]).astype(np.int32)
        enc.encode(sym, _MASK_MODEL, np.zeros(sym.size), scales[k].astype(np.float64))
    if d.size:
        E.encode_differences(enc, d, pick)
    for p, c, z in zip(full, codes, zeros, strict=True):
        on = ~z[gid]
        if on.any():
            E._encode_values(enc, p[:, on], _scales(c, gid)[:, on])
    body = enc.body()
    esc_bytes = _escapes(parts)
    return bytes([pick | flag, nibbles[0] | nibbles[1] << 4, nibbles[2]]) + E.write_uvarint(len(esc_bytes)) \
        + esc_bytes + E.write_uvarint(len(body)) + body


def _decode_masked(dec: E.RangeReader, model: tuple[np.ndarray, np.ndarray], pick: int, rows: list[int],
                   cols: int, gid: np.ndarray, n: int) -> list[np.ndarray]:
    """The parts of a :data:`ZEROS` stream's body being read by ``dec`` (its masks, codes and values)."""
    likely, scales = model
    zeros: list[np.ndarray] = []
    for i in range(sum(1 for r in rows if r)):
        k = np.zeros(n, np.int64) if not i else np.where(zeros[-1], 1, 2)
        sym = dec.laplace(scales[k][None, :], 1, n, 0, 1).ravel()
        if sym.min(initial=0) < 0:
            raise FormatError(None, "corrupted integer stream (mask)")
        zeros.append((sym == 1) != likely[k])
    nbs = [_blocks(r) for r in rows if r]
    total = sum(nb * int(np.count_nonzero(~z)) for nb, z in zip(nbs, zeros, strict=True))
    d = dec.laplace(np.full((1, 1), E.DELTA_SCALES[pick]), total, 1, 0, E.DELTA_LIMIT, total + 1).ravel()
    last, at, codes = np.full(n, HALF_BIAS, dtype=np.int64), 0, []
    for i, (nb, z) in enumerate(zip(nbs, zeros, strict=True)):
        on = ~z
        part = d[at:at + nb * int(on.sum())].reshape(nb, -1)
        at += part.size
        c = np.full((nb, n), HALF_BIAS, dtype=np.int64)
        c[:, on] = (np.cumsum(part.ravel()).reshape(part.shape) + HALF_BIAS) if not i else part + last[on]
        if c.size and (c.min() < 0 or c.max() > HALF_TOP):
            raise FormatError(None, "corrupted integer stream (scales)")
        last[on] = c[-1, on]
        codes.append(c)
    out, j = [], 0
    for r in rows:
        p = np.zeros((r, cols), np.int64)
        if r:
            on = ~zeros[j][gid]
            if on.any():
                p[:, on] = dec.laplace(_scales(codes[j], gid)[:, on], r, int(on.sum()))
            j += 1
        out.append(p)
    return out
