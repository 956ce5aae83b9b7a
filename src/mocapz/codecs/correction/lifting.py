"""Error-bounded, smooth coding of a residual matrix: closed-loop interpolating lifting.

A residual ``x`` ``(frames, columns)`` is coded with a tolerance ``tol`` ``(frames, columns)`` such that every
decoded sample is within ``tol`` of ``x`` (``|x - y| <= tol`` element-wise, up to float rounding):

* the frames are padded (edge repeat) to ``n = k * 2**levels + 1``; the coarse knots ``0, S, 2S, ...``
  (``S = 2**levels``) are quantised with one step per column (twice the smallest tolerance on the knots),
  and coded as time differences of their integers;
* each finer level ``l`` (spacing ``h = 2**l``) predicts its new samples (odd multiples of ``h``) from the
  already *decoded* coarser samples with the 4-point Deslauriers-Dubuc filter ``(-1, 9, 9, -1) / 16``
  (linear next to the ends). A prediction within ``tol`` of the value codes 0 (dead zone); otherwise the
  detail is the *smallest* number of steps ``STEP * tol`` that brings it within ``tol`` (the decoded
  curve bends just enough, staying on the prediction's side: rounding to the nearest step would flip the
  error's sign and add white noise, i.e. jitter and foot skate).

With every detail zero the decoded curve is the Deslauriers-Dubuc subdivision of the knots: smooth (close to
C2), so the correction adds little acceleration energy (jitter); a non-zero detail adds a local bump of the
scale of its level. A continued clip (a stream's block after the one before it) starts from the decoded frame
before it, and its levels' first samples take the 4-point filter with the decoded frames before that one.
The integers go to the range coder (:func:`mocapz.format.entropy.encode_int_matrix`).
"""

from __future__ import annotations

import numpy as np

from mocapz.codecs.correction.compiled import kernels
from mocapz.errors import FormatError
from mocapz.format import entropy_parts
from mocapz.format.entropy import HAVE_CONSTRICTION, decode_int_matrix, encode_int_matrix, read_uvarint, write_uvarint
from mocapz.format.entropy_shared import decode_int_matrix as read_shared
from mocapz.format.entropy_shared import encode_int_matrix as shared_int_matrix

BIG = 1e30  # tolerance standing for "any value will do" (a column that moves no point)
STEP = 1.0  # detail step, in tolerances (<= 2)


def level_factor(level: int, shrink: float) -> float:
    """Share of a sample's tolerance used at lifting level ``level`` (0: the finest), ``shrink ** level``:
    coarser samples are coded tighter, so that finer ones are predicted well enough to need no detail (a
    detail at a fine level is a bump of a few frames: acceleration energy, i.e. jitter)."""
    return float(shrink**level)


def plan(frames: int, levels: int) -> tuple[int, int]:
    """``(levels, padded frames)``: at most ``levels`` lifting levels, fewer for short clips."""
    lv = int(max(0, min(levels, int(np.floor(np.log2(max(frames - 1, 1)))))))
    span = 1 << lv
    n = -(-(max(frames, 1) - 1) // span) * span + 1
    return lv, n


def _pad(a: np.ndarray, n: int) -> np.ndarray:
    """``a`` ``(frames, columns)`` extended to ``n`` rows by repeating its last row."""
    if a.shape[0] >= n:
        return a[:n]
    return np.concatenate([a, np.repeat(a[-1:], n - a.shape[0], axis=0)])


def _predict(y: np.ndarray, h: int, ghost: np.ndarray | None = None) -> tuple[slice, np.ndarray]:
    """New sample rows (the slice of the odd multiples of ``h``) of level spacing ``h`` and their predictions
    ``(m, columns)`` from the decoded samples of spacing ``2h`` in ``y`` ``(n, columns)`` (strided views, no
    gathers). ``ghost`` ``(columns,)``: a continued clip's decoded value ``2h`` rows before its first (NaN where
    unknown), which gives its first new sample the 4-point filter too (no kink where the clip meets the one
    before it)."""
    n = y.shape[0]
    new = slice(h, n - 1, 2 * h)
    m = len(range(h, n - 1, 2 * h))
    left, right = y[0 : 2 * h * m : 2 * h], y[2 * h : 2 * h * (m + 1) : 2 * h]  # rows idx - h, idx + h
    pred = 0.5 * (left + right)
    # the 4-point filter where idx - 3h >= 0 and idx + 3h <= n - 1: t = 1 .. hi - 1 (idx = h + 2ht)
    hi = min(m, (n - 1 - 4 * h) // (2 * h) + 1)
    if hi > 1:
        pred[1:hi] = (9.0 * (left[1:hi] + right[1:hi]) - (left[0 : hi - 1] + right[2 : hi + 1])) / 16.0
    if ghost is not None and hi >= 1:
        four = (9.0 * (left[0] + right[0]) - (ghost + right[1])) / 16.0
        pred[0] = np.where(np.isnan(ghost), pred[0], four)
    return new, pred


def split_prefix(prefix: np.ndarray | None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """A continued clip's first knot ``(columns,)`` and its ghosts ``(columns, levels)`` (level ``l``'s: the decoded
    value ``2 ** (l + 1)`` rows before the first knot, NaN where unknown) from ``prefix`` ``(columns,)`` (no
    ghosts) or ``(columns, 1 + levels)`` (:func:`.context.prefix`)."""
    if prefix is None or prefix.ndim == 1:
        return prefix, None
    return prefix[:, 0], prefix[:, 1:]


def _ghost(ghosts: np.ndarray | None, level: int) -> np.ndarray | None:
    return None if ghosts is None or level >= ghosts.shape[1] else ghosts[:, level]


def _kernel_ghosts(ghosts: np.ndarray | None, cols: int) -> np.ndarray:
    """The ghosts as the compiled kernels take them: ``(levels, columns)``, ``(0, columns)`` for none."""
    return np.zeros((0, cols)) if ghosts is None else np.ascontiguousarray(ghosts.T, dtype=np.float64)


def quantise(x: np.ndarray, tol: np.ndarray, levels: int, shrink: float = 1.0,
             compiled: bool | None = None, prefix: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Quantise residual ``x`` ``(frames, columns)`` within ``tol`` ``(frames, columns)`` (> 0, ``BIG`` =
    free), level ``l`` within ``tol * shrink ** l``.

    Returns the integers ``(padded frames, columns)`` (coarse knot differences, then the details level by
    level) and the decoded residual ``(frames, columns)`` (what :func:`decode` gives). ``compiled``: code the
    details with the compiled kernel (:mod:`.liftkernels`, the same bits), None: when it is worth loading.
    ``prefix`` ``(columns,)``: a continued clip (a stream's block after the one before it): the decoded value of
    the frame before the first, known to the decoder, is the first knot (:func:`grid`); the integers' first row
    is then zero and not stored (:func:`pack`), but on the columns where the prefix is NaN (a marker missing in
    that frame), whose first knot is coded as in a clip of its own. ``(columns, 1 + levels)``: the same, with
    each level's ghost (:func:`split_prefix`), from which the level's first new sample is predicted as inside a
    clip: the decoded curve meets the one before it without a kink.
    """
    frames, cols = x.shape
    prefix, ghosts = split_prefix(prefix)
    x, tol = grid(x, prefix), grid(tol, prefix)
    lv, n = plan(x.shape[0], levels)
    xp, tp = _pad(x, n), _pad(np.minimum(tol, BIG), n)
    y = np.zeros((n, cols))
    span = 1 << lv
    step0 = 2.0 * level_factor(lv, shrink) * tp[::span].min(axis=0)  # (columns,)
    if prefix is None:
        q0 = np.round(xp[::span] / step0).astype(np.int64)
        y[::span] = q0 * step0
    else:
        origin = _origin(prefix)
        q0 = np.round((xp[::span] - origin) / step0).astype(np.int64)
        q0[0, ~np.isnan(prefix)] = 0
        y[::span] = origin + q0 * step0
    rows = slice(0, frames) if prefix is None else slice(1, frames + 1)
    kern = kernels(frames, "liftkernels") if compiled is None else (kernels(0, "liftkernels") if compiled else None)
    if kern is not None and lv and np.isfinite(xp).all():
        q = np.empty((n, cols), dtype=np.int64)
        q[:len(q0)] = np.diff(q0, axis=0, prepend=0)
        factors = np.array([level_factor(level, shrink) for level in range(lv)])
        kern.details(np.ascontiguousarray(xp), np.ascontiguousarray(tp), y, q, lv, factors, STEP, len(q0),
                     _kernel_ghosts(ghosts, cols))
        return q, y[rows]
    parts = [np.diff(q0, axis=0, prepend=0)]
    for level in range(lv - 1, -1, -1):
        h = 1 << level
        idx, pred = _predict(y, h, _ghost(ghosts, level))
        t = level_factor(level, shrink) * tp[idx]
        step = STEP * t
        d = xp[idx] - pred
        q = (np.sign(d) * np.ceil(np.maximum(np.abs(d) - t, 0.0) / step)).astype(np.int64)
        y[idx] = pred + q * step
        parts.append(q)
    return np.concatenate(parts), y[rows]


def grid(a: np.ndarray, prefix: np.ndarray | None) -> np.ndarray:
    """The rows the lifting runs on: ``a`` ``(frames, ...)`` itself, or for a continued clip (``prefix`` given) a
    row before the first, standing for the frame before the clip (a copy of the first row: its tolerance or
    level, which :func:`quantise` and :func:`decode` both use for the knots' step)."""
    return a if prefix is None else np.concatenate([a[:1], a])


def row_groups(frames: int, levels: int) -> list[int]:
    """Rows of each part of :func:`quantise`'s integers: the coarse knots, then the details of each level,
    coarse to fine."""
    lv, n = plan(frames, levels)
    return [len(range(0, n, 1 << lv))] + [len(range(1 << lv_, n - 1, 2 << lv_)) for lv_ in range(lv - 1, -1, -1)]


SPLIT_TWO, SPLIT_LEVELS = 0, 1  # c.res layouts: knots + all details, or knots + each level's details
FIRST_APART = 2  # layout flag: the knots' first row (absolute values, the rest are time differences) is a stream
# of its own (its magnitudes would widen the scales of every knot of its columns: a block of a clip pays it each)
JOINT = 4  # layout flag: the parts (knots, each level's details) in one range stream (:mod:`.entropy_parts`)


def _origin(prefix: np.ndarray) -> np.ndarray:
    """What a continued clip's knots are coded from: the prefix, 0 where it is NaN."""
    return np.where(np.isnan(prefix), 0.0, prefix)


def _groups(frames: int, levels: int, split: int, continued: bool = False) -> list[int]:
    rows = row_groups(frames + continued, levels)
    if continued:  # the first knot is the frame before the clip's: not stored
        rows = [rows[0] - 1, *rows[1:]]
    rows = rows if split & SPLIT_LEVELS else [rows[0], sum(rows[1:])]
    return [1, rows[0] - 1, *rows[1:]] if split & FIRST_APART and rows[0] > 1 else rows


def pack(q: np.ndarray, frames: int, levels: int, prefix: np.ndarray | None = None,
         groups: np.ndarray | None = None) -> bytes:
    """The bytes of the integers of :func:`quantise` for a clip of ``frames`` frames: a layout byte, then range
    coded streams each after its uvarint byte length: the coarse knots (time differences, the first row
    absolute; the first row a stream of its own where that is smaller), then the details, all levels in one
    stream or one stream per level, whichever is smaller (the levels' magnitudes differ by orders and one
    stream's adaptive scales mix them; each stream costs scales per column, which a short clip or block may not
    win back). ``prefix``: a continued clip's (:func:`quantise`): the integers' first row is stored only where
    the prefix is NaN, as a stream of its own first (if any). ``groups`` ``(columns,)``: the columns' groups
    (joints, markers), which may share their streams' scales (:mod:`mocapz.format.entropy_shared`; :func:`read`
    is then given the same)."""
    if not q.shape[1]:
        return b""
    prefix = split_prefix(prefix)[0]
    continued, head = prefix is not None, b""
    if prefix is not None:
        free = np.isnan(prefix)
        if free.any():
            b = encode_int_matrix(q[:1, free])
            head = write_uvarint(len(b)) + b
        q = q[1:]
    coded: dict[tuple[int, int], bytes] = {}  # each stream once: (first row, rows) -> its bytes

    def part(pos: int, rows: int) -> bytes:
        if (pos, rows) not in coded:
            part_q = q[pos:pos + rows]
            coded[pos, rows] = encode_int_matrix(part_q) if groups is None else shared_int_matrix(part_q, groups)
        return coded[pos, rows]

    def layout(split: int) -> bytes:
        out, pos = bytearray([split]) + head, 0
        for rows in _groups(frames, levels, split, continued):
            b = part(pos, rows)
            out += write_uvarint(len(b)) + b
            pos += rows
        return bytes(out)

    knots = row_groups(frames, levels)[0]
    first = FIRST_APART if not continued and knots > 1 \
        and len(part(0, 1)) + len(part(1, knots - 1)) < len(part(0, knots)) else 0
    candidates = [layout(first | split) for split in (SPLIT_TWO, SPLIT_LEVELS)]
    if groups is not None and HAVE_CONSTRICTION:  # one stream for every part (a short clip's, a block's)
        parts = np.split(q, np.cumsum(_groups(frames, levels, SPLIT_LEVELS | first, continued))[:-1])
        candidates.append(bytes([JOINT | first]) + head + entropy_parts.encode(parts, groups))
    return min(candidates, key=len)


def read(data: bytes, frames: int, cols: int, levels: int, prefix: np.ndarray | None = None,
         groups: np.ndarray | None = None) -> np.ndarray:
    """The integers of :func:`pack` for a clip of ``frames`` x ``cols`` values (each stream's shape is checked
    before anything is allocated), for a continued clip the same ``prefix``."""
    prefix = split_prefix(prefix)[0]
    continued = prefix is not None
    if cols == 0:
        return np.zeros((0, 0), dtype=np.int64)
    if not data or data[0] > SPLIT_LEVELS | FIRST_APART | JOINT \
            or (data[0] & FIRST_APART and (continued or row_groups(frames, levels)[0] < 2)) \
            or (data[0] & JOINT and (data[0] & SPLIT_LEVELS or groups is None)):
        raise FormatError(None, "corrupted correction stream (layout)")
    parts, pos = [], 1
    if prefix is not None:
        free = np.isnan(prefix)
        row0 = np.zeros((1, cols), dtype=np.int64)
        if free.any():
            size, pos = read_uvarint(data, pos)
            if pos + size > len(data):
                raise FormatError(None, "corrupted correction stream (part length)")
            row0[:, free] = decode_int_matrix(data[pos:pos + size], (1, int(free.sum())))
            pos += size
        parts.append(row0)
    if data[0] & JOINT:
        rows = _groups(frames, levels, SPLIT_LEVELS | data[0] & FIRST_APART, continued)
        return np.concatenate([*parts, *entropy_parts.decode(data[pos:], rows, cols, groups)])
    for rows in _groups(frames, levels, data[0], continued):
        size, pos = read_uvarint(data, pos)
        if pos + size > len(data):
            raise FormatError(None, "corrupted correction stream (part length)")
        part = data[pos:pos + size]
        parts.append(decode_int_matrix(part, (rows, cols)) if groups is None else
                     read_shared(part, (rows, cols), groups))
        pos += size
    if pos != len(data):
        raise FormatError(None, "corrupted correction stream (trailing bytes)")
    return np.concatenate(parts)


def decode(q_all: np.ndarray, tol: np.ndarray, levels: int, shrink: float = 1.0,
           prefix: np.ndarray | None = None) -> np.ndarray:
    """Inverse of :func:`quantise`: the decoded residual ``(frames, columns)`` from the integers (:func:`read`)
    and the same ``tol``, ``levels``, ``shrink`` and ``prefix``."""
    return _decode_grid(q_all, grid(tol, split_prefix(prefix)[0]), levels, shrink, prefix)


def _decode_grid(q_all: np.ndarray, tol: np.ndarray, levels: int, shrink: float, prefix: np.ndarray | None
                 ) -> np.ndarray:
    """:func:`decode` from the tolerances of the lifting's rows (:func:`grid`)."""
    prefix, ghosts = split_prefix(prefix)
    n_rows, cols = tol.shape
    rows = slice(0, n_rows) if prefix is None else slice(1, n_rows)
    if cols == 0:
        return np.zeros((rows.stop - rows.start, 0))
    lv, n = plan(n_rows, levels)
    tp = _pad(np.minimum(tol, BIG), n)
    span = 1 << lv
    n0 = len(range(0, n, span))
    y = np.zeros((n, cols))
    step0 = 2.0 * level_factor(lv, shrink) * tp[::span].min(axis=0)
    y[::span] = _knots(q_all[:n0], step0, prefix)
    pos = n0
    for level in range(lv - 1, -1, -1):
        h = 1 << level
        idx, pred = _predict(y, h, _ghost(ghosts, level))
        m = pred.shape[0]
        q = q_all[pos : pos + m]
        if q.shape[0] != m:
            raise FormatError(None, "corrupted correction stream (detail count)")
        y[idx] = pred + q * (STEP * level_factor(level, shrink) * tp[idx])
        pos += m
    return y[rows]


def _knots(q: np.ndarray, step: np.ndarray, prefix: np.ndarray | None) -> np.ndarray:
    """The decoded knots from their integers' time differences ``q`` ``(knots, columns)`` and step ``(columns,)``
    (a continued clip's from the prefix, its first knot)."""
    if prefix is None:
        return np.cumsum(q, axis=0) * step
    return _origin(prefix) + np.cumsum(q, axis=0) * step


def decode_table(q_all: np.ndarray, tol_col: np.ndarray, halves: np.ndarray, lev: np.ndarray, groups: np.ndarray,
                 levels: int, shrink: float = 1.0, prefix: np.ndarray | None = None) -> np.ndarray:
    """:func:`decode` with ``tol = tol_col[None, :] * halves[lev][:, groups]`` (``tol_col`` ``(columns,)``, a
    table ``halves``, indices ``lev`` ``(frames, groups)`` into it and ``groups`` ``(columns,)`` into ``lev``'s
    columns): the same bits. The compiled kernel (when loaded) reads the tolerances from the table, without a
    frames x columns array of them."""
    first, ghosts = split_prefix(prefix)
    lev = grid(lev, first)
    frames, cols = lev.shape[0], groups.size
    lv, n = plan(frames, levels)
    kern = kernels(frames, "liftkernels", decoding=True) if cols and lv and q_all.shape[0] >= n else None
    if kern is None:
        return _decode_grid(q_all, tol_col[None, :] * halves[lev][:, groups], levels, shrink, prefix)
    span = 1 << lv
    n0 = len(range(0, n, span))
    rows = np.minimum(np.arange(n0) * span, frames - 1)  # the knots (the last may lie in the padding)
    knots = np.minimum(tol_col[None, :] * halves[lev[rows]][:, groups], BIG)
    y = np.empty((n, cols))  # every row is written: the knots here, the details by the kernel
    y[::span] = _knots(q_all[:n0], 2.0 * level_factor(lv, shrink) * knots.min(axis=0), first)
    factors = np.array([level_factor(level, shrink) for level in range(lv)])
    kern.decode_details(np.ascontiguousarray(q_all, dtype=np.int64), np.ascontiguousarray(tol_col, dtype=np.float64),
                        np.ascontiguousarray(halves, dtype=np.float64), np.ascontiguousarray(lev, dtype=np.int64),
                        np.ascontiguousarray(groups, dtype=np.int64), y, lv, factors, STEP, n0, frames, BIG,
                        _kernel_ghosts(ghosts, cols))
    return y[:frames] if prefix is None else y[1:frames]
