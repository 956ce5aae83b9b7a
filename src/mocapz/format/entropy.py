"""Entropy coding of integer arrays.

The main coder is constriction's range coder with a quantized Laplace model whose scale adapts per block
of rows and per column (the scales travel in the stream in quarter octaves, as differences coded by the range
coder itself: a few bits each, so that a short block of a clip pays little for them). Values beyond the model's range
are escaped and stored exactly. Where constriction is not installed (no wheel for aarch64 Linux), the same
streams are written with zstd on zig-zag byte planes; the first byte of every stream says which coder
wrote it, so either side can read both kinds when its coder is present.
"""

from __future__ import annotations

import sys
from types import ModuleType
from typing import Any

import numpy as np

from mocapz import _jit, aot
from mocapz.errors import FormatError
from mocapz.format import rangewriter
from mocapz.format.entropy_costs import (  # noqa: F401  (re-exported: the scale search's costs)
    HIST_VALUES,
    _candidate_bits,
    _histogram,
    _laplace_bits,
    code_bits,
    scale_codes,
)
from mocapz.format.planes import (  # noqa: F401  (re-exported: the integer streams' public helpers)
    MAX_COUNT,
    pack_uint64,
    pack_zigzag_columns,
    planes_rows,
    read_uvarint,
    safe_zstd_decompress,
    unpack_planes,
    unpack_uint64,
    unpack_zigzag_columns,
    unpack_zigzag_rows,
    unpack_zigzag_running,
    unzigzag,
    write_uvarint,
    zigzag,
    zstd_capacity,
)
from mocapz.format.rangewriter import RangeWriter

try:  # pragma: no cover - exercised on platforms without wheels
    import constriction

    HAVE_CONSTRICTION = True
except ImportError:  # pragma: no cover
    constriction = None
    HAVE_CONSTRICTION = False

CODER_RANGE = 1  # constriction range coder, quantized Laplace, block scales
CODER_ZSTD = 2  # zstd on zig-zag byte planes
CODER_RANGE_PACKED = 3  # as CODER_RANGE, its scale bytes zstd-packed (uvarint length first) when that is smaller
CODER_RANGE_DELTA = 4  # as CODER_RANGE, quarter-octave scales coded first, as differences, in the range stream

LIMIT = (1 << 15) - 1  # |symbol| < LIMIT coded directly; LIMIT marks an escape
BLOCK = 256  # rows per scale block
SPARSE = 0.25  # a matrix with at most this share of non-zeros is also tried as zstd byte planes
DELTA_LIMIT = 128  # |difference| of two quarter-octave scale codes
SCALE_STEPS = 8  # scale quantisation: s = 2 ** ((q - 64) / 8)
QUARTER_BIAS = 32  # CODER_RANGE_DELTA's scales: s = 2 ** ((q - 32) / 4), q in 0 .. QUARTER_TOP
QUARTER_TOP = 127
DELTA_SCALES = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0)  # Laplace scales of the scale codes' differences (one byte picks)
CHUNK_VALUES = 1 << 16  # values range coded per call of the coder (its per-value arrays: peak memory)
LAZY_VALUES = 10 << 20  # values decoded in one stream from which numba is loaded for the range decoder (constriction
# decodes a 5,000-frame clip's streams in milliseconds: loading numba, about 0.5 s, pays on clips of about 100,000)


_DELTA_MODEL = constriction.stream.model.QuantizedLaplace(-DELTA_LIMIT, DELTA_LIMIT) if HAVE_CONSTRICTION else None


# ---------------------------------------------------------------- block scales
def _block_scales(values: np.ndarray) -> np.ndarray:
    """Coder 1's scale codes ``(blocks, columns)`` uint8, ``s = 2 ** ((q - 64) / 8)``: the guess and every
    second code from 8 below to 24 above it (:func:`_scale_codes`)."""
    return _scale_codes(values, SCALE_STEPS, 64, range(-SCALE_STEPS, 3 * SCALE_STEPS + 1, 2), 255).astype(np.uint8)


def _quarter_scales(values: np.ndarray) -> np.ndarray:
    """Coder 4's scale codes ``(blocks, columns)`` in quarter octaves, ``s = 2 ** ((q - 32) / 4)``: every code
    from 4 below to 12 above the guess (:func:`_scale_codes`)."""
    return _scale_codes(values, 4, QUARTER_BIAS, range(-4, 13), QUARTER_TOP)


def _scale_codes(values: np.ndarray, steps: int, bias: int, offsets: range, top: int) -> np.ndarray:
    """:func:`~.entropy_costs.scale_codes` per block of :data:`BLOCK` rows."""
    return scale_codes(values, BLOCK, steps, bias, offsets, top, _range_kernels(values.size))


def _block_scale(q: np.ndarray, steps: int = SCALE_STEPS, bias: int = 64) -> np.ndarray:
    """Laplace scales ``(blocks, columns)`` of block codes ``q``: ``s = 2 ** ((q - bias) / steps)``."""
    return 2.0 ** ((q.astype(np.float64) - bias) / steps)


def _encode_values(enc: RangeWriter, v: np.ndarray, scale: np.ndarray, row0: int = 0) -> bytes:
    """Range code the values of ``v`` ``(rows, columns)`` (row by row, clipped to the model's range; the escape
    mark where beyond) into ``enc`` under the Laplace scales ``scale`` ``(blocks, columns)`` of their blocks of
    :data:`BLOCK` rows (``v``'s first row being row ``row0`` of the matrix the blocks count). Returns the packed
    escaped values (b"" without any)."""
    enc.laplace(v, scale, row0, BLOCK, LIMIT)
    esc = v[np.abs(v) >= LIMIT]
    return pack_uint64(zigzag(esc)) if esc.size else b""


def range_writer(values: int = 0) -> RangeWriter:
    """A writer of a range-coded stream of about ``values`` values: the compiled one where the decoder's kernels
    would be used (:func:`range_decoder`), else constriction's; both write the same words."""
    return rangewriter.writer(_range_kernels(values))


# ---------------------------------------------------------------- public API
def encode_int_matrix(values: np.ndarray, coder: int | None = None, *, sparse: bool = False) -> bytes:
    """Entropy-code a ``(rows, columns)`` integer matrix (e.g. prediction residuals).

    Columns are modelled independently with a Laplace scale per block of 256 rows; best for
    zero-centred residuals. A mostly-zero matrix whose non-zeros come in runs (tightening levels, the
    finest lifting details, clustered on a few frames) is smaller as zstd-packed byte planes, which the
    encoder then chooses (``coder`` None). Returns a self-describing byte string (shape included). ``sparse``: the
    matrix is mostly zero (the zstd planes' search, :func:`~mocapz.format.planes.pack_zigzag_columns`).
    """
    v = np.ascontiguousarray(values, dtype=np.int64)
    if v.ndim == 1:
        v = v[:, None]
    rows, cols = v.shape
    head = write_uvarint(rows) + write_uvarint(cols)
    if coder is None:
        if not HAVE_CONSTRICTION:
            coder = CODER_ZSTD
        elif v.size == 0 or np.count_nonzero(v) > SPARSE * v.size:
            return encode_int_matrix(v, CODER_RANGE_DELTA)
        else:  # the zstd trial first: its work space is let go before the range coder's arrays are made
            packed = encode_int_matrix(v, CODER_ZSTD, sparse=True)
            ranged = encode_int_matrix(v, CODER_RANGE_DELTA)
            return packed if len(packed) < len(ranged) else ranged
    if coder == CODER_ZSTD or v.size == 0:
        return bytes([CODER_ZSTD]) + head + pack_zigzag_columns(v, sparse)
    if coder == CODER_RANGE_DELTA:
        return _encode_delta(v, head)
    q = _block_scales(v)
    enc = range_writer(v.size)
    esc = _encode_values(enc, v, _block_scale(q))
    body = enc.body()
    scales = pack_uint64(q.ravel())
    kind, scales = (CODER_RANGE_PACKED, write_uvarint(len(scales)) + scales) if len(scales) + 2 < q.size \
        else (CODER_RANGE, q.tobytes())
    return bytes([kind]) + head + scales + write_uvarint(len(esc)) + esc + write_uvarint(len(body)) + body


def _encode_delta(v: np.ndarray, head: bytes) -> bytes:
    """The CODER_RANGE_DELTA stream of ``v`` ``(rows, columns)``: the scale codes' differences (in block, then
    column order, from QUARTER_BIAS) and the values, in one range-coded body."""
    q, pick = _delta_scales(v)
    enc = range_writer(v.size)
    _encode_scale_codes(enc, q, pick)
    esc = _encode_values(enc, v, _block_scale(q, 4, QUARTER_BIAS))
    body = enc.body()
    return bytes([CODER_RANGE_DELTA]) + head + bytes([pick]) + write_uvarint(len(esc)) + esc \
        + write_uvarint(len(body)) + body


def _delta_scales(v: np.ndarray) -> tuple[np.ndarray, int]:
    """CODER_RANGE_DELTA's scale codes ``(blocks, columns)`` of ``v`` and the pick of the Laplace scale their
    differences are coded with (an index into :data:`DELTA_SCALES`)."""
    q = _quarter_scales(v)
    diffs = np.abs(np.diff(q.ravel(), prepend=QUARTER_BIAS))[:, None].astype(np.float64)
    return q, int(np.argmin([_laplace_bits(diffs, None, np.array([d]))[0] for d in DELTA_SCALES]))


def _encode_scale_codes(enc: RangeWriter, q: np.ndarray, pick: int) -> None:
    """Range code the scale codes ``q`` as differences (block, then column order, from QUARTER_BIAS)."""
    encode_differences(enc, np.diff(q.ravel(), prepend=QUARTER_BIAS), pick)


def encode_differences(enc: RangeWriter, d: np.ndarray, pick: int) -> None:
    """Range code scale codes' differences ``d`` ``(n,)`` under the Laplace scale ``DELTA_SCALES[pick]`` on
    ``[-DELTA_LIMIT, DELTA_LIMIT]`` (constriction's ``_DELTA_MODEL``)."""
    enc.laplace(np.asarray(d, dtype=np.int64).reshape(-1, 1), np.full((1, 1), DELTA_SCALES[pick]), 0,
                max(d.size, 1), DELTA_LIMIT)


def _decode_scale_codes(dec: RangeReader, pick: int, nb: int, cols: int) -> np.ndarray:
    """Inverse of :func:`_encode_scale_codes`: the codes ``(nb, cols)``, range checked (FormatError)."""
    diffs = dec.laplace(np.full((1, 1), DELTA_SCALES[pick]), nb * cols, 1, 0, DELTA_LIMIT, nb * cols + 1)
    q = np.cumsum(diffs.ravel()) + QUARTER_BIAS
    if q.size and (q.min() < 0 or q.max() > QUARTER_TOP):
        raise FormatError(None, "corrupted integer stream (scales)")
    return q.reshape(nb, cols)


def decode_int_matrix(data: bytes, shape: tuple[int, int] | None = None) -> np.ndarray:
    """Inverse of :func:`encode_int_matrix`: the ``(rows, columns)`` int64 matrix.

    ``shape`` is the shape the caller expects (a stream claiming another is a FormatError before anything is
    decoded); without it, the stream's own shape is bounded by its size.
    """
    buf = memoryview(data)
    if len(buf) < 3:
        raise FormatError(None, "truncated integer stream")
    coder = buf[0]
    rows, pos = read_uvarint(buf, 1)
    cols, pos = read_uvarint(buf, pos)
    if shape is not None and (rows, cols) != tuple(shape):
        raise FormatError(None, f"corrupted integer stream (shape {(rows, cols)} where {tuple(shape)} is expected)")
    if rows * cols > 1 << 34:
        raise FormatError(None, "corrupted integer stream (absurd size)")
    if coder == CODER_ZSTD:
        return unpack_zigzag_columns(bytes(buf[pos:]), rows, cols)
    if coder not in (CODER_RANGE, CODER_RANGE_PACKED, CODER_RANGE_DELTA):
        raise FormatError(None, f"unknown entropy coder id {coder}")
    if not HAVE_CONSTRICTION:
        raise FormatError(None, "this stream was written by the range coder; install 'constriction'")
    if rows * cols == 0:
        return np.zeros((rows, cols), dtype=np.int64)
    nb = max(1, -(-rows // BLOCK))
    if coder == CODER_RANGE_DELTA:
        return _decode_delta(buf, pos, rows, cols, nb)
    if coder == CODER_RANGE_PACKED:
        size, pos = read_uvarint(buf, pos)
        end = pos + size
        if end > len(buf):
            raise FormatError(None, "truncated integer stream (scales)")
        packed = unpack_uint64(bytes(buf[pos:end]), nb * cols)
        if np.any(packed > 255):
            raise FormatError(None, "corrupted integer stream (scales)")
        q = packed.astype(np.uint8).reshape(nb, cols)
    else:
        end = pos + nb * cols
        if end > len(buf):
            raise FormatError(None, "truncated integer stream (scales)")
        q = np.frombuffer(bytes(buf[pos:end]), dtype=np.uint8).reshape(nb, cols)
    esc_bytes, body = _escapes_and_body(buf, end)
    try:
        dec = range_decoder(body, rows * cols)
        sym, marks = _decode_values(dec, _block_scale(q), rows, cols)
    except Exception as exc:  # constriction raises plain exceptions on corrupt input
        raise FormatError(None, f"corrupted entropy-coded data ({exc})") from None
    return _unescape(sym, esc_bytes, marks)


def _escapes_and_body(buf: memoryview, pos: int) -> tuple[bytes, bytes]:
    """A range stream's escape bytes and body (uvarint length before each), from ``pos``."""
    n_esc, pos = read_uvarint(buf, pos)
    esc_bytes = bytes(buf[pos : pos + n_esc])
    pos += n_esc
    n_body, pos = read_uvarint(buf, pos)
    body = bytes(buf[pos : pos + n_body])
    if len(body) != n_body or len(esc_bytes) != n_esc or len(body) % 4:
        raise FormatError(None, "truncated integer stream (body)")
    return esc_bytes, body


def _decode_values(dec: RangeReader, scale: np.ndarray, rows: int, cols: int,
                   row0: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The values ``(rows, cols)`` under the scales ``scale`` ``(blocks, cols)`` of their :data:`BLOCK` rows (the
    first being row ``row0`` of the matrix the blocks count), and the flat positions of their escape marks."""
    out = dec.laplace(scale, rows, cols, row0)
    return out, np.flatnonzero(np.abs(out.ravel()) >= LIMIT)


class RangeReader:
    """A range-coded stream being read: constriction's ``RangeDecoder`` (the reference), :data:`CHUNK_VALUES`
    values per call, as coded (small arrays)."""

    def __init__(self, words: np.ndarray) -> None:
        self.dec = constriction.stream.queue.RangeDecoder(words)

    def laplace(self, scale: np.ndarray, rows: int, cols: int, row0: int = 0, limit: int = LIMIT,
                block: int = BLOCK) -> np.ndarray:
        """The next ``(rows, cols)`` symbols, int64, each under the quantized Laplace(0, ``scale[(row0 + row) //
        block, col]``) on ``[-limit, limit]``."""
        model = constriction.stream.model.QuantizedLaplace(-limit, limit)
        out = np.empty((rows, cols), np.int64)
        step = max(1, CHUNK_VALUES // max(cols, 1))
        means = np.zeros(min(rows, step) * cols)
        for a in range(0, rows, step):
            part = out[a:a + step]
            blocks = np.arange(row0 + a, row0 + a + len(part)) // block
            part[...] = self.dec.decode(model, means[:part.size], scale[blocks].ravel()).reshape(part.shape)
        return out


class CompiledRangeReader(RangeReader):
    """:class:`RangeReader` with the numba kernel (:mod:`.rangekernels`): the same symbols, two to four times as
    fast. A point outside the range (corrupt data) is a FormatError."""

    def __init__(self, words: np.ndarray, kernels: ModuleType | aot.Kernels) -> None:
        self.words, self.kernels = words, kernels
        self.state = kernels.begin(words)

    def laplace(self, scale: np.ndarray, rows: int, cols: int, row0: int = 0, limit: int = LIMIT,
                block: int = BLOCK) -> np.ndarray:
        out = np.empty((rows, cols), np.int64)
        scale = np.ascontiguousarray(scale, dtype=np.float64)
        if self.kernels.decode_laplace(self.words, self.state, scale, row0, block, limit, out):
            raise FormatError(None, "corrupted entropy-coded data (the range decoder's point left its range)")
        return out


_KERNELS: dict[str, Any] = {}


def range_decoder(body: bytes, values: int = 0) -> RangeReader:
    """A reader of the range-coded ``body`` (its 32-bit words), about to decode ``values`` values: the compiled
    one where numba is installed, not turned off (:mod:`mocapz._jit`) and worth loading (loaded already, or
    :data:`LAZY_VALUES` values), else constriction's. Both give the same symbols."""
    words = np.frombuffer(body, dtype=np.uint32).copy()
    kern = _range_kernels(values)
    return RangeReader(words) if kern is None else CompiledRangeReader(words, kern)


def _range_kernels(values: int) -> ModuleType | aot.Kernels | None:
    if not _jit.enabled():
        return None
    if "mod" in _KERNELS:
        return _KERNELS["mod"]
    if (ahead := aot.kernels("range")) is not None:  # compiled ahead of time: nothing to load
        _KERNELS["mod"] = ahead
        return ahead
    if ("numba" not in sys.modules and values < LAZY_VALUES) or not _jit.room_to_compile():
        return None
    try:
        from mocapz.format import rangekernels
    except ImportError:  # numba not installed
        _KERNELS["mod"] = None
        return None
    _warm(rangekernels)
    _KERNELS["mod"] = rangekernels
    return rangekernels


def _warm(kernels: ModuleType) -> None:
    """Compile (or load from numba's cache) the kernel now, with the argument types of the real calls: not later
    inside a caller's resource limits (an address-space cap would abort the process)."""
    words = np.zeros(2, dtype=np.uint32)
    kernels.decode_laplace(words, kernels.begin(words), np.ones((1, 1)), 0, BLOCK, LIMIT, np.empty((1, 1), np.int64))


def _unescape(sym: np.ndarray, esc_bytes: bytes, marks: np.ndarray) -> np.ndarray:
    """``sym`` with its escape marks (flat positions ``marks``) replaced by the values stored aside."""
    if marks.size:
        if not esc_bytes:
            raise FormatError(None, "corrupted integer stream (escapes missing)")
        sym.reshape(-1)[marks] = unzigzag(unpack_uint64(esc_bytes, marks.size))
    return sym


def _decode_delta(buf: memoryview, pos: int, rows: int, cols: int, nb: int) -> np.ndarray:
    """The values of a CODER_RANGE_DELTA stream whose shape has been read (``pos``: just after it)."""
    if pos >= len(buf) or buf[pos] >= len(DELTA_SCALES):
        raise FormatError(None, "corrupted integer stream (scale model)")
    pick = buf[pos]
    esc_bytes, body = _escapes_and_body(buf, pos + 1)
    try:
        dec = range_decoder(body, rows * cols)
        q = _decode_scale_codes(dec, pick, nb, cols)
        sym, marks = _decode_values(dec, _block_scale(q, 4, QUARTER_BIAS), rows, cols)
    except FormatError:
        raise
    except Exception as exc:  # constriction raises plain exceptions on corrupt input
        raise FormatError(None, f"corrupted entropy-coded data ({exc})") from None
    return _unescape(sym, esc_bytes, marks)
