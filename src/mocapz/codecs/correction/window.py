"""The correction's streams laid out for random access, and the decoding of a window of frames from them.

A clip of at least :data:`SEEK_MIN` frames (format 3 of ``c.head``) codes its integers as
:func:`~.lifting.quantise` makes them (the same values as format 2), but packed so that frames ``[a, b)`` decode
from a few chunks and segments (:mod:`mocapz.format.seekable`):

* ``c.res``: a layout byte, then streams each after its uvarint length: the coarse knots as running values
  (chunks of ``SEEK_CHUNK / 2 ** depth`` knots), then the details, all levels in one stream or one stream a
  level (the smaller), in segments of about :data:`SEGMENT_VALUES` values;
* ``c.levels``: the largest tightening level on the knots of every group (uvarints: the knots' quantisation
  step, which format 2 takes from every knot's tolerance), then the levels ``(frames, groups)`` as running
  values (chunks of :data:`LEVEL_CHUNK` frames, or whole where they are mostly still).

A window needs, at lifting level ``l`` (spacing ``h = 2 ** l``), the samples within ``3 h`` of the samples it
needs at the level below (the 4-point Deslauriers-Dubuc filter's reach): about ``3 * 2 ** depth`` frames on each
side in all. :func:`decode_window` inverse-lifts only those, with the same float operations in the same order as
:func:`~.lifting.decode`: the window's values are the full decode's to the bit.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mocapz.codecs.correction.lifting import BIG, STEP, level_factor, plan, row_groups
from mocapz.errors import FormatError
from mocapz.format.entropy import read_uvarint, write_uvarint
from mocapz.format.seekable import decode_segments, encode_segments, pack_running, read_running

SEEK_CHUNK = 1024  # frames per chunk of the knots' running values (a chunk's first row costs a few bits more
# per column than a time difference: 1 to 2 % of a 2,000-frame clip's knots at 512 frames)
SEEK_MIN = 1024  # clips from this many frames are coded seekable (shorter ones decode whole in a few ms)
LEVEL_CHUNK = 128  # frames per chunk of the levels' running values (small numbers: a chunk's first row costs little)
SEGMENT_VALUES = 4096  # values per segment of a detail stream (a segment costs its coder's flush and two lengths,
# about 8 bytes: under 1 % of a dense stream's 4,096 values; a seek decodes up to that many before its rows)
ONE_STREAM, STREAM_A_LEVEL = 0, 1  # c.res layouts of the details


def seekable(frames: int) -> bool:
    """Whether a clip of ``frames`` frames is coded with the seekable layout (``c.head`` format 3)."""
    return frames >= SEEK_MIN


def _knot_chunk(depth: int, frames: int) -> int:
    return max(1, SEEK_CHUNK >> plan(frames, depth)[0])


def _detail_starts(frames: int, depth: int, split: int, cols: int) -> list[range]:
    """The segment starts of every detail stream of layout ``split``: every :data:`SEGMENT_VALUES` values (a
    seek decodes at most that much before the rows it needs, in a range-coded stream)."""
    step = max(1, -(-SEGMENT_VALUES // max(cols, 1)))
    return [range(0, max(rows, 1), step) for rows in _detail_rows(frames, depth, split)]


def _detail_rows(frames: int, depth: int, split: int) -> list[int]:
    rows = row_groups(frames, depth)[1:]
    return rows if split == STREAM_A_LEVEL else [sum(rows)]


def pack_res(q: np.ndarray, frames: int, depth: int) -> bytes:
    """The seekable ``c.res`` of :func:`~.lifting.quantise`'s integers ``q`` ``(padded frames, columns)``."""
    if not q.shape[1]:
        return b""
    rows, cols = row_groups(frames, depth), q.shape[1]
    knots = write_uvarint_bytes(pack_running(np.cumsum(q[:rows[0]], axis=0), _knot_chunk(depth, frames)))
    best = None
    for split in (ONE_STREAM, STREAM_A_LEVEL):
        out, pos = bytearray([split]) + knots, rows[0]
        for n, starts in zip(_detail_rows(frames, depth, split), _detail_starts(frames, depth, split, cols),
                             strict=True):
            out += write_uvarint_bytes(encode_segments(q[pos:pos + n], starts))
            pos += n
        best = out if best is None or len(out) < len(best) else best
    return bytes(best)


def write_uvarint_bytes(b: bytes) -> bytes:
    return write_uvarint(len(b)) + b


def _streams(data: bytes, frames: int, depth: int) -> tuple[int, list[bytes]]:
    """The layout byte and the length-prefixed streams (the knots', then the details') of a seekable ``c.res``."""
    if not data or data[0] not in (ONE_STREAM, STREAM_A_LEVEL):
        raise FormatError(None, "corrupted correction stream (layout)")
    out, pos = [], 1
    for _ in range(1 + len(_detail_rows(frames, depth, data[0]))):
        size, pos = read_uvarint(data, pos)
        if pos + size > len(data):
            raise FormatError(None, "corrupted correction stream (part length)")
        out.append(data[pos:pos + size])
        pos += size
    if pos != len(data):
        raise FormatError(None, "corrupted correction stream (trailing bytes)")
    return data[0], out


def read_res(data: bytes, frames: int, cols: int, depth: int) -> np.ndarray:
    """All the integers of a seekable ``c.res`` in :func:`~.lifting.quantise`'s order (what format 2's
    :func:`~.lifting.read` gives)."""
    if cols == 0:
        return np.zeros((0, 0), dtype=np.int64)
    rows = row_groups(frames, depth)
    split, parts = _streams(data, frames, depth)
    knots = read_running(parts[0], (rows[0], cols), _knot_chunk(depth, frames))
    out = [np.diff(knots, axis=0, prepend=0)]
    for part, n, starts in zip(parts[1:], _detail_rows(frames, depth, split),
                               _detail_starts(frames, depth, split, cols), strict=True):
        segs = decode_segments(part, (n, cols), starts)
        out += [segs[i] for i in range(len(starts))]
    return np.concatenate(out)


def pack_levels(levels: np.ndarray, frames: int, depth: int) -> bytes:
    """The seekable ``c.levels`` of the tightening levels ``(frames, groups)``."""
    lv, n = plan(frames, depth)
    knot_rows = np.minimum(np.arange(0, n, 1 << lv), frames - 1)
    top = levels[knot_rows].max(axis=0) if levels.size else np.zeros(levels.shape[1], dtype=np.int64)
    return b"".join(write_uvarint(int(t)) for t in top) + pack_running(levels, LEVEL_CHUNK)


def read_levels(data: bytes, frames: int, groups: int, a: int = 0, b: int | None = None,
                memo: dict[str, object] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The largest level on the knots ``(groups,)`` and the levels of frames ``[a, b)`` ``(b - a, groups)``
    (``memo``: :func:`mocapz.format.seekable.read_running`'s)."""
    top, runs = _level_top(data, groups)
    return top, _window_levels(runs, frames, groups, a, frames if b is None else b, memo)


def _level_top(data: bytes, groups: int) -> tuple[np.ndarray, bytes]:
    """A ``c.levels``' largest level on the knots ``(groups,)`` and the bytes of its levels' running values."""
    top, pos = [], 0
    for _ in range(groups):
        value, pos = read_uvarint(data, pos)
        top.append(value)
    top_arr = np.array(top, dtype=np.int64)
    if top_arr.size and top_arr.max() > 60:
        raise FormatError(None, "corrupted correction levels")
    return top_arr, data[pos:]


def _window_levels(runs: bytes, frames: int, groups: int, a: int, b: int, memo: dict[str, object] | None
                   ) -> np.ndarray:
    """The levels of frames ``[a, b)`` ``(b - a, groups)`` from their running values' bytes ``runs``."""
    lev = read_running(runs, (frames, groups), LEVEL_CHUNK, a, b, memo)
    if lev.size and (lev.min() < 0 or lev.max() > 60):
        raise FormatError(None, "corrupted correction levels")
    return lev


def reach(frames: int, depth: int, a: int, b: int) -> list[tuple[int, int]]:
    """Per lifting level ``l`` (0: the finest) up to the knots' (``depth`` levels: ``depth + 1`` entries), the
    padded positions ``[lo, hi]`` whose samples frames ``[a, b)`` need."""
    lv, n = plan(frames, depth)
    lo, hi, out = a, b - 1, [(a, b - 1)]
    for level in range(lv):
        h = 1 << level
        lo, hi = max(0, lo - 3 * h), min(n - 1, hi + 3 * h)
        out.append((lo, hi))
    return out


@dataclass(frozen=True)
class Running:
    """What the windows of one clip's seekable streams share (:func:`open_running`): the largest level on the
    knots ``(groups,)``, the ``c.res`` layout and streams, and what the windows have decoded so far, kept for the
    next ones (the chunks of the levels' and the knots' running values: :func:`mocapz.format.seekable.read_running`'s
    ``memo``; the detail streams' unpacked planes where zstd-packed, their scale model and segment table where range
    coded: :func:`mocapz.format.seekable.decode_segments`' ``kept``)."""

    top: np.ndarray
    runs: bytes
    split: int
    parts: list[bytes]
    levels: dict[str, object] = field(default_factory=dict)
    knots: dict[str, object] = field(default_factory=dict)
    details: dict[bytes, Any] = field(default_factory=dict)


def open_running(data: bytes, lev_data: bytes, groups: np.ndarray, frames: int, depth: int) -> Running:
    """:class:`Running` of a seekable ``c.res`` (``data``) and ``c.levels`` (``lev_data``) whose columns' groups
    are ``groups`` ``(columns,)``, nothing decoded yet (a reader keeps it)."""
    top, runs = _level_top(lev_data, int(groups.max(initial=-1)) + 1)
    _window_levels(runs, frames, top.size, 0, 0, None)  # its layout checked
    split, parts = _streams(data, frames, depth)
    return Running(top, runs, split, parts)


def decode_window(data: bytes, lev_data: bytes, tol_col: np.ndarray, halves: np.ndarray, groups: np.ndarray,
                  frames: int, depth: int, shrink: float, a: int, b: int, running: Running | None = None
                  ) -> np.ndarray:
    """The decoded residual of frames ``[a, b)`` ``(b - a, columns)``, from a seekable ``c.res`` (``data``) and
    ``c.levels`` (``lev_data``), the tolerances ``tol_col[c] * halves[level]`` (capped at BIG) of
    :func:`~.lifting.decode_table`: the rows of the full decode, to the bit. ``running``: the streams' running
    values' chunks decoded so far, kept for later windows (:func:`open_running`; the same numbers)."""
    cols = groups.size
    lv, n = plan(frames, depth)
    span = 1 << lv
    ranges = reach(frames, depth, a, b)
    k_lo, k_hi = ranges[lv][0] // span, -(-ranges[lv][1] // span)  # the knots around the coarsest reach
    lo, hi = k_lo * span, k_hi * span  # the window of padded positions worked on
    w0, w1 = min(lo, frames - 1), min(hi, frames - 1) + 1  # the frames whose levels the window reads
    if running is None:
        top, lev = read_levels(lev_data, frames, int(groups.max(initial=-1)) + 1, w0, w1)
    else:
        top, lev = running.top, _window_levels(running.runs, frames, running.top.size, w0, w1, running.levels)
    split, parts = _streams(data, frames, depth) if running is None else (running.split, running.parts)
    knots = read_running(parts[0], (row_groups(frames, depth)[0], cols), _knot_chunk(depth, frames), k_lo,
                         k_hi + 1, None if running is None else running.knots)
    y = np.zeros((hi - lo + 1, cols))
    kmin = np.minimum(tol_col * halves[top[groups]], BIG)
    y[::span] = knots * (2.0 * level_factor(lv, shrink) * kmin)

    tol = np.minimum(tol_col[None, :] * halves[lev][:, groups], BIG)  # (w1 - w0, columns) the capped tolerances

    details = _details(parts[1:], frames, depth, split, cols, ranges, None if running is None else running.details)
    for level in range(lv - 1, -1, -1):
        h = 1 << level
        t0, t1, q = details[level]
        if t1 < t0:
            continue
        m = len(range(h, n - 1, 2 * h))
        top4 = min(m, (n - 1 - 4 * h) // (2 * h) + 1)
        at, count = h + 2 * h * t0 - lo, t1 - t0 + 1  # the samples' rows in y: every 2h from ``at``
        left, right = _every(y, at - h, 2 * h, count), _every(y, at + h, 2 * h, count)
        pred = 0.5 * (left + right)
        f0, f1 = max(t0, 1) - t0, min(t1, top4 - 1) - t0 + 1  # the 4-point filter's samples (1 <= t < top4)
        if f1 > f0:
            far = at + 2 * h * f0
            pred[f0:f1] = (9.0 * (left[f0:f1] + right[f0:f1])
                           - (_every(y, far - 3 * h, 2 * h, f1 - f0) + _every(y, far + 3 * h, 2 * h, f1 - f0))) / 16.0
        rows = np.minimum(h + 2 * h * np.arange(t0, t1 + 1), frames - 1) - w0  # the samples' frames (padding: the last)
        y[at:at + 2 * h * (count - 1) + 1:2 * h] = pred + q * (STEP * level_factor(level, shrink) * tol[rows])
    return y[a - lo:b - lo]


def _every(y: np.ndarray, start: int, step: int, count: int) -> np.ndarray:
    """Rows ``start, start + step, ...`` (``count`` of them) of ``y``: a view."""
    if start < 0 or start + step * (count - 1) >= len(y):
        raise FormatError(None, "corrupted correction window")  # the reach keeps every neighbour inside
    return y[start:start + step * (count - 1) + 1:step]


def _details(parts: list[bytes], frames: int, depth: int, split: int, cols: int, ranges: list[tuple[int, int]],
             kept: dict[bytes, Any] | None = None) -> dict[int, tuple[int, int, np.ndarray]]:
    """Per level, the first and last sample index ``t`` within its reach and their integers ``(samples,
    columns)``, decoding only the segments holding them."""
    lv, counts, offsets, streams, bounds = _detail_plan(frames, depth, split, cols)
    want: list[tuple[int, int, int]] = []  # (level, t0, t1)
    for k, level in enumerate(range(lv - 1, -1, -1)):
        h = 1 << level
        lo, hi = ranges[level]
        t0, t1 = max(0, -(-(lo - h) // (2 * h))), min(counts[k] - 1, (hi - h) // (2 * h))
        want.append((level, t0, t1))
    spans: dict[int, list[tuple[int, int, int]]] = {}  # stream -> (level, first row, stop row) in it
    for k, (level, t0, t1) in enumerate(want):
        if t1 >= t0:
            s, base = (k, 0) if split == STREAM_A_LEVEL else (0, offsets[k])
            spans.setdefault(s, []).append((level, base + t0, base + t1 + 1))
    out = {level: (t0, t1, np.zeros((0, cols), dtype=np.int64)) for level, t0, t1 in want}
    for s, rows_wanted in spans.items():  # each stream decoded once, its segments the levels' rows lie in
        starts, (rows, step) = streams[s], bounds[s]
        # the segments each level's rows lie in (those starting before its stop and ending after its first row)
        per = {level: list(range(r0 // step, min(len(starts), -(-r1 // step)))) for level, r0, r1 in rows_wanted}
        idx = sorted({j for js in per.values() for j in js})
        segs = decode_segments(parts[s], (rows, cols), starts, idx, max(r1 for _, _, r1 in rows_wanted), kept)
        for level, r0, r1 in rows_wanted:
            mine = per[level]
            block = segs[mine[0]] if len(mine) == 1 else np.concatenate([segs[j] for j in mine])
            first = starts[mine[0]]
            t0, t1, _ = out[level]
            out[level] = (t0, t1, block[r0 - first:r1 - first])
    return out


@functools.lru_cache(maxsize=64)
def _detail_plan(frames: int, depth: int, split: int, cols: int
                 ) -> tuple[int, list[int], list[int], list[range], list[tuple[int, int]]]:
    """What :func:`_details` needs of a clip's shape: the lifting levels, the samples of every detail level, where
    each level starts in one stream, every stream's segment starts and its rows and segment length."""
    lv = plan(frames, depth)[0]
    counts = row_groups(frames, depth)[1:]
    offsets = [int(o) for o in np.concatenate([[0], np.cumsum(counts)])]
    streams = _detail_starts(frames, depth, split, cols)
    rows = counts if split == STREAM_A_LEVEL else [offsets[-1]]
    return lv, counts, offsets, streams, [(r, s.step) for r, s in zip(rows, streams, strict=True)]
