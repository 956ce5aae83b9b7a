"""Integer matrices coded so that a range of their rows decodes without the rows before it (random access).

Two layouts, built on :mod:`mocapz.format.entropy`'s coders:

* **segments** (:func:`encode_segments`): a ``(rows, columns)`` matrix cut at given rows into segments. Range
  coded, the Laplace scales are those of :func:`~mocapz.format.entropy.encode_int_matrix` (per block of
  :data:`~mocapz.format.entropy.BLOCK` rows and column, quarter octaves), coded once, as differences, in a
  small range stream of their own, and every segment is a range stream of its own (its escapes and body, each
  after its uvarint length): a segment costs its coder's flush and two lengths, not its scales. A mostly-zero
  matrix that zstd's byte planes code smaller is stored whole that way (decoded whole, in a fraction of a
  millisecond, and cut).
* **running** (:func:`pack_running`): a matrix of running values (a time series of small steps: the coarse
  knots of a lifting, a level per frame) as its differences within chunks of ``chunk`` rows (segments) and,
  apart, the differences of the chunks' first rows (a short stream, decoded whole): rows ``[a, b)`` need the
  chunks holding them, nothing before.

The segment starts and shapes are given by the caller (from the file's header), never read from the stream;
every length is checked before anything is allocated.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from mocapz.errors import FormatError
from mocapz.format import entropy
from mocapz.format.entropy import decode_int_matrix, encode_int_matrix, read_uvarint, write_uvarint

SEG_ZSTD, SEG_RANGE = 0, 1  # the layouts of :func:`encode_segments`
RUN_WHOLE, RUN_CHUNKS = 0, 1  # the layouts of :func:`pack_running`


def encode_segments(values: np.ndarray, starts: Sequence[int]) -> bytes:
    """The bytes of ``values`` ``(rows, columns)`` int cut at the rows ``starts`` (increasing, the first 0; the
    decoder is given the same list): the smaller of the segmented range coding and (for a mostly-zero matrix)
    zstd's byte planes of the whole."""
    v = np.ascontiguousarray(values, dtype=np.int64)
    _check_starts(starts, v.shape[0])
    if v.size == 0 or not entropy.HAVE_CONSTRICTION:
        return bytes([SEG_ZSTD]) + encode_int_matrix(v, entropy.CODER_ZSTD)
    ranged = _encode_range(v, starts)
    if np.count_nonzero(v) <= entropy.SPARSE * v.size:
        packed = bytes([SEG_ZSTD]) + encode_int_matrix(v, entropy.CODER_ZSTD, sparse=True)
        if len(packed) < len(ranged):
            return packed
    return ranged


def _encode_range(v: np.ndarray, starts: Sequence[int]) -> bytes:
    q, pick = entropy._delta_scales(v)
    enc = entropy.range_writer(v.size)
    entropy._encode_scale_codes(enc, q, pick)
    head = enc.body()
    out = bytearray([SEG_RANGE, pick]) + write_uvarint(len(head)) + head
    scale = entropy._block_scale(q, 4, entropy.QUARTER_BIAS)
    for a, b in zip(starts, [*starts[1:], v.shape[0]], strict=True):
        enc = entropy.range_writer(v.size)
        esc = entropy._encode_values(enc, v[a:b], scale, a)
        body = enc.body()
        out += write_uvarint(len(esc)) + esc + write_uvarint(len(body)) + body
    return bytes(out)


def decode_segments(data: bytes, shape: tuple[int, int], starts: Sequence[int],
                    wanted: list[int] | None = None, until: int | None = None,
                    kept: dict[bytes, Any] | None = None) -> dict[int, np.ndarray]:
    """Segments of an :func:`encode_segments` stream of a ``shape`` matrix cut at ``starts``: ``{index: rows}``
    for the segment indices ``wanted`` (all by default), the others not decoded (a range-coded stream) or not
    kept; rows from ``until`` on are not needed (the segments holding them end there). ``kept``: where what every
    window of a stream reads is kept by its bytes (a reader's): a zstd-packed stream's unpacked planes
    (decompressed once), a range-coded stream's scale model and segment table (read once)."""
    rows, cols = shape
    _check_starts(starts, rows)
    nexts = [*starts[1:], rows]

    def end(i: int) -> int:  # where segment ``i``'s rows needed end
        return nexts[i] if until is None else max(starts[i] + 1, min(nexts[i], until))

    wanted = list(range(len(starts))) if wanted is None else sorted(set(wanted))
    if wanted and not 0 <= wanted[0] <= wanted[-1] < len(starts):
        raise ValueError(f"segments {wanted} of {len(starts)}")
    buf = memoryview(data)
    if not buf or buf[0] not in (SEG_ZSTD, SEG_RANGE):
        raise FormatError(None, "corrupted seekable stream (layout)")
    if buf[0] == SEG_ZSTD:  # decompressed whole, only the wanted segments' rows unpacked
        if not wanted:
            return {}
        unpacked = None if kept is None else kept.get(data)
        if unpacked is None:
            unpacked = entropy.unpack_planes(_zstd_body(bytes(buf[1:]), rows, cols), rows * cols)
            if kept is not None:
                kept[data] = unpacked
        return dict(zip(wanted, entropy.planes_rows(unpacked, rows, cols, [(starts[i], end(i)) for i in wanted]),
                        strict=True))
    if not entropy.HAVE_CONSTRICTION:
        raise FormatError(None, "this stream was written by the range coder; install 'constriction'")
    model = None if kept is None else kept.get(data)
    if model is None:  # a reader's: every segment's place; else those up to the last wanted
        model = _range_model(buf, rows, cols, len(starts) if kept is not None else (wanted[-1] + 1 if wanted else 0))
        if kept is not None:
            kept[data] = model
    scale, table = model
    out = {}
    for i in wanted:
        esc_at, esc_size, body_at, body_end = table[i]
        if (body_end - body_at) % 4:
            raise FormatError(None, "corrupted seekable stream (body)")
        a, n = starts[i], end(i) - starts[i]
        dec = entropy.range_decoder(bytes(buf[body_at:body_end]), rows * cols)
        sym, marks = _guard(lambda dec=dec, a=a, n=n: entropy._decode_values(dec, scale, n, cols, a))
        out[i] = _unescape(sym, bytes(buf[esc_at:esc_at + esc_size]), marks, complete=n == nexts[i] - a)
    return out


def _range_model(buf: memoryview, rows: int, cols: int, count: int
                 ) -> tuple[np.ndarray, list[tuple[int, int, int, int]]]:
    """A range-coded :func:`encode_segments` stream's Laplace scales ``(blocks, columns)`` and the places of its
    first ``count`` segments: ``(escapes at, escapes size, body at, body end)`` each (their lengths read, their bytes
    not)."""
    if len(buf) < 2 or buf[1] >= len(entropy.DELTA_SCALES):
        raise FormatError(None, "corrupted seekable stream (scale model)")
    pick = buf[1]
    size, pos = read_uvarint(buf, 2)
    head = _take(buf, pos, size)
    pos += size
    nb = max(1, -(-rows // entropy.BLOCK))
    dec = entropy.range_decoder(head, rows * cols)
    scale = entropy._block_scale(_guard(lambda: entropy._decode_scale_codes(dec, pick, nb, cols)), 4,
                                 entropy.QUARTER_BIAS)
    table = []
    for _ in range(count):
        esc_size, pos = read_uvarint(buf, pos)
        esc_at = pos
        pos += esc_size
        if pos > len(buf):
            raise FormatError(None, "truncated seekable stream")
        body_size, pos = read_uvarint(buf, pos)
        body_at = pos
        pos += body_size
        if pos > len(buf):
            raise FormatError(None, "truncated seekable stream")
        table.append((esc_at, esc_size, body_at, pos))
    return scale, table


def _unescape(sym: np.ndarray, esc: bytes, marks: np.ndarray, complete: bool) -> np.ndarray:
    """``sym`` with its escape marks replaced by the values stored aside (a segment decoded only in part has the
    first of them)."""
    if not complete and marks.size:
        values = entropy.unzigzag(entropy.unpack_uint64(esc, at_most=entropy.MAX_COUNT)) if esc else np.zeros(0)
        if values.size < marks.size:
            raise FormatError(None, "corrupted integer stream (escapes missing)")
        sym.reshape(-1)[marks] = values[:marks.size]
        return sym
    return entropy._unescape(sym, esc, marks)


def _zstd_body(data: bytes, rows: int, cols: int) -> bytes:
    """The byte-plane stream of a CODER_ZSTD :func:`~mocapz.format.entropy.encode_int_matrix` stream of a
    ``(rows, cols)`` matrix, its shape checked."""
    if len(data) < 3 or data[0] != entropy.CODER_ZSTD:
        raise FormatError(None, "corrupted seekable stream (zstd layout)")
    r, pos = read_uvarint(data, 1)
    c, pos = read_uvarint(data, pos)
    if (r, c) != (rows, cols):
        raise FormatError(None, f"corrupted integer stream (shape {(r, c)} where {(rows, cols)} is expected)")
    return data[pos:]


def _guard(call):  # noqa: ANN001, ANN202
    try:
        return call()
    except FormatError:
        raise
    except Exception as exc:  # constriction raises plain exceptions on corrupt input
        raise FormatError(None, f"corrupted entropy-coded data ({exc})") from None


def _take(buf: memoryview, pos: int, size: int) -> bytes:
    if pos + size > len(buf):
        raise FormatError(None, "truncated seekable stream")
    return bytes(buf[pos:pos + size])


def _check_starts(starts: Sequence[int], rows: int) -> None:
    rising = starts.step > 0 if isinstance(starts, range) else all(b > a for a, b in zip(starts, starts[1:],
                                                                                            strict=False))
    if not starts or starts[0] != 0 or not rising or (rows and starts[-1] >= rows):
        raise ValueError(f"segment starts {starts[:4]}... do not cut {rows} rows")


# ---------------------------------------------------------------- running values
def chunk_starts(rows: int, chunk: int) -> list[int]:
    """The first row of every chunk of ``chunk`` rows (``[0]`` for an empty matrix)."""
    return list(range(0, max(rows, 1), chunk))


def pack_running(values: np.ndarray, chunk: int) -> bytes:
    """The bytes of running values ``(rows, columns)`` int, a layout byte first: :data:`RUN_CHUNKS`, the
    differences of the chunks' first rows (the first from 0; an :func:`~mocapz.format.entropy.encode_int_matrix`
    stream after its uvarint length), then the differences within every chunk of ``chunk`` rows, its first row
    left out (:func:`encode_segments`, a segment a chunk); or :data:`RUN_WHOLE`, the differences of every row in
    zstd's byte planes, where that is no larger (a mostly-still series: unpacked and summed whole in a fraction
    of a millisecond, it needs no chunks)."""
    v = np.ascontiguousarray(values, dtype=np.int64)
    rows, cols = v.shape
    firsts = encode_int_matrix(np.diff(v[::chunk], axis=0, prepend=0))
    inner = np.diff(v, axis=0)  # row r - 1: v[r] - v[r - 1]; the rows of the chunks' first rows left out
    keep = np.ones(max(rows - 1, 0), dtype=bool)
    keep[chunk - 1::chunk] = False
    starts = _inner_starts(rows, chunk)
    chunked = bytes([RUN_CHUNKS]) + write_uvarint(len(firsts)) + firsts \
        + (encode_segments(inner[keep], starts) if keep.any() else b"")
    if np.count_nonzero(inner) <= entropy.SPARSE * max(inner.size, 1):
        whole = bytes([RUN_WHOLE]) + encode_int_matrix(np.diff(v, axis=0, prepend=0), entropy.CODER_ZSTD)
        if len(whole) <= len(chunked):
            return whole
    return chunked


def _inner_starts(rows: int, chunk: int) -> list[int]:
    """Where each chunk's inner rows (all but its first) start in :func:`pack_running`'s inner matrix (chunks of
    one row have none and no segment)."""
    starts, pos = [], 0
    for a in range(0, rows, chunk):
        n = min(rows, a + chunk) - a - 1
        if n > 0:
            starts.append(pos)
            pos += n
    return starts


def read_running(data: bytes, shape: tuple[int, int], chunk: int, a: int = 0, b: int | None = None,
                 memo: dict[str, Any] | None = None) -> np.ndarray:
    """Rows ``[a, b)`` ``(b - a, columns)`` int64 of a :func:`pack_running` stream of a ``shape`` matrix, decoding
    only the chunks holding them. ``memo``: a dict kept for this stream (a reader's), where the chunks decoded
    are kept whole and found by later calls (the same integers)."""
    rows, cols = shape
    b = rows if b is None else b
    if not 0 <= a <= b <= rows or chunk < 1:
        raise ValueError(f"rows [{a}, {b}) of {rows} in chunks of {chunk}")
    if not data or data[0] not in (RUN_WHOLE, RUN_CHUNKS):
        raise FormatError(None, "corrupted seekable stream (running layout)")
    if data[0] == RUN_WHOLE:
        if memo is None:
            return entropy.unpack_zigzag_running(_zstd_body(data[1:], rows, cols), rows, cols, a, b)
        if "whole" not in memo:  # a mostly-still series: summed whole in a fraction of a millisecond
            memo["whole"] = entropy.unpack_zigzag_running(_zstd_body(data[1:], rows, cols), rows, cols, 0, rows)
        return np.array(memo["whole"][a:b])
    size, pos = read_uvarint(data, 1)
    nchunks = len(range(0, rows, chunk))
    firsts = None if memo is None else memo.get("firsts")
    if firsts is None:
        firsts = np.cumsum(decode_int_matrix(_take(memoryview(data), pos, size), (nchunks, cols)), axis=0)
        if memo is not None:
            memo["firsts"] = firsts
    if a == b:
        return np.zeros((0, cols), dtype=np.int64)
    first, last = a // chunk, (b - 1) // chunk
    done: dict[int, np.ndarray] = {} if memo is None else memo.setdefault("chunks", {})
    todo = [c for c in range(first, last + 1) if c not in done]
    if todo:
        # a memo keeps whole chunks; without one, rows from b on are not decoded
        _decode_chunks(data[pos + size:], rows, cols, chunk, firsts, todo, b if memo is None else rows, done)
    out = np.empty((b - a, cols), dtype=np.int64)
    for c in range(first, last + 1):
        lo = c * chunk
        part = done[c]
        s, e = max(a, lo), min(b, lo + part.shape[0])
        out[s - a:e - a] = part[s - lo:e - lo]
    return out


def _decode_chunks(inner_data: bytes, rows: int, cols: int, chunk: int, firsts: np.ndarray, todo: list[int],
                   b: int, done: dict[int, np.ndarray]) -> None:
    """The rows of chunks ``todo`` (those before row ``b``) of a :data:`RUN_CHUNKS` stream into ``done``."""
    nchunks = len(range(0, rows, chunk))
    # the segment index of every chunk with inner rows (chunks of one row have none)
    seg_of = np.cumsum([min(rows, c + chunk) - c > 1 for c in range(0, rows, chunk)]) - 1
    needs = [c for c in todo if min(rows, c * chunk + chunk) - c * chunk > 1 and c * chunk + 1 < b]
    wanted = [int(seg_of[c]) for c in needs]
    starts = _inner_starts(rows, chunk)
    last = todo[-1]
    # the inner rows up to row b - 1 (chunk ``last``'s inner rows before it)
    until = starts[int(seg_of[last])] + (b - 1 - last * chunk) if needs and needs[-1] == last else None
    segs = decode_segments(inner_data, (rows - nchunks, cols), starts, wanted, until) if wanted else {}
    for c in todo:
        lo = c * chunk
        n = min(rows, lo + chunk) - lo
        part = np.empty((n, cols), dtype=np.int64)
        part[0] = firsts[c]
        if n > 1 and c * chunk + 1 < b:  # the inner rows decoded (those up to b - 1)
            inner = segs[int(seg_of[c])]
            n = 1 + inner.shape[0]
            part = part[:n]
            np.cumsum(inner, axis=0, out=part[1:])
            part[1:] += firsts[c]
        done[c] = part
