"""Varints and zstd-packed byte planes: the small building blocks of every integer stream.

:func:`pack_uint64` stores non-negative integers as their low bytes plane by plane (all first bytes, then all
second bytes, ...), zstd-compressed: small values cost little, and a mostly-zero matrix (a sparse plane of runs)
packs very small. :func:`pack_zigzag_columns` does so for a signed matrix, column after column.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator

import numpy as np
import zstandard

from mocapz.errors import FormatError

MAX_COUNT = 1 << 31  # most values in one integer stream
COLUMN_VALUES = 1 << 16  # values zigzagged per step of pack_zigzag_columns (its temporaries stay small)
_LOCAL = threading.local()  # each thread's zstd compressors (one is not safe across threads)
LEVEL = 19  # zstd's level of every byte-plane stream but where a caller asks another
# zstd's parameters of LEVEL for the stream's size (its window, hash and chain tables), but its search: the
# optimal parser without btultra2's second pass (STRATEGY_BTOPT), matches of at least 4 bytes. On the byte planes
# of 6 shared files' streams (94 of them, 7.4 MB) 274,248 B against level 19's 275,328 in 0.23-0.29 times its time;
# over every shared file's first 3,000 frames quant -0.01 %, pga -0.20 %, lossless +0.06 % bytes, and a quant
# encode of 06_13 about a fifth faster (target_length 999 packed 0.1-0.2 % smaller, a little slower)
STRATEGY = zstandard.STRATEGY_BTOPT
MIN_MATCH = 4
# the largest table (log2 of its entries, and of the window's bytes) of a compressor kept for the next stream: a
# context is about 4 bytes per entry of its hash and chain tables plus its window, so one kept for every stream
# size a clip has (06_13's patterns at max distortion 1 %: 13 sets, up to window 2**20, tables 2**21) held 32 MB
# of resident memory from the first large stream to the end of the process; 2**17 keeps each under about 1.2 MB
KEEP_LOG = 17
# a sparse matrix's planes (the zstd trial of a mostly-zero matrix: the correction's finer lifting details, most of
# their bytes zero runs) of at least SPARSE_BYTES: the optimal parser's search depth SPARSE_SEARCH_LOG (log2 of its
# tree's searches) in place of the level's. On every shared motion file's quant encode (the 73 such streams of
# 64 kB and more, 10.5 MB) about 0.45 times the time for the same bytes in all (13 whole files 0.1-1.7 % smaller,
# one 0.3 % larger); smaller streams gain little time and come out larger as often as smaller
SPARSE_SEARCH_LOG = 1
SPARSE_BYTES = 1 << 16


def _compressor(level: int, size: int, sparse: bool = False) -> zstandard.ZstdCompressor:
    """This thread's zstd compressor for ``size`` bytes at ``level`` (:data:`LEVEL`: with :data:`STRATEGY` and
    :data:`MIN_MATCH`, and for a ``sparse`` matrix's planes of at least :data:`SPARSE_BYTES` the search depth
    :data:`SPARSE_SEARCH_LOG`), made once per parameter set where its tables are small (:data:`KEEP_LOG`): the same
    bytes as a new one per call (each ``compress`` is a frame of its own), without making its context again for
    each of a clip's many small streams; a large stream's context (megabytes of tables, a few calls a clip) is not
    kept."""
    made = getattr(_LOCAL, "zstd", None)
    if made is None:
        made = _LOCAL.zstd = {}
    if level != LEVEL:  # zstd's own parameters for the size
        z = made.get(level)
        if z is None:
            z = made[level] = zstandard.ZstdCompressor(level=level)
        return z
    p = zstandard.ZstdCompressionParameters.from_level(level, source_size=size)
    search = SPARSE_SEARCH_LOG if sparse and size >= SPARSE_BYTES else p.search_log
    key = (p.window_log, p.chain_log, p.hash_log, search, p.target_length)
    z = made.get(key)
    if z is None:
        z = zstandard.ZstdCompressor(compression_params=zstandard.ZstdCompressionParameters(
            window_log=p.window_log, chain_log=p.chain_log, hash_log=p.hash_log, search_log=search,
            min_match=MIN_MATCH, target_length=p.target_length, strategy=STRATEGY))
        if max(p.window_log, p.chain_log, p.hash_log) <= KEEP_LOG:
            made[key] = z
    return z


# ---------------------------------------------------------------- varints
def write_uvarint(value: int) -> bytes:
    out = bytearray()
    value = int(value)
    if value < 0:
        raise ValueError("uvarint must be non-negative")
    while True:
        b = value & 0x7F
        value >>= 7
        if value:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


def read_uvarint(buf: bytes | memoryview, pos: int) -> tuple[int, int]:
    value, shift = 0, 0
    while True:
        if pos >= len(buf):
            raise FormatError(None, "truncated data (varint runs past the end)")
        b = buf[pos]
        pos += 1
        value |= (b & 0x7F) << shift
        if not b & 0x80:
            if value >> 64:
                raise FormatError(None, "corrupted data (varint over 64 bits)")
            return value, pos
        shift += 7
        if shift > 63:
            raise FormatError(None, "corrupted data (varint too long)")


def read_uvarints(buf: bytes | memoryview, pos: int, count: int) -> tuple[np.ndarray, int]:
    """``count`` uvarints from ``pos`` at once: their values ``(count,)`` uint64 and the position after them; the
    values and the errors of :func:`read_uvarint` called ``count`` times (a damaged run is read that way)."""
    if count <= 0:
        return np.zeros(0, dtype=np.uint64), pos
    b = np.frombuffer(buf, dtype=np.uint8)[pos : pos + 10 * count]
    ends = np.flatnonzero(b < 0x80)[:count]
    starts = np.concatenate([[0], ends[:-1] + 1])
    lengths = ends - starts + 1
    if ends.size < count or lengths.max() > 10 or np.any(b[ends[lengths == 10]] > 1):
        values = []
        for _ in range(count):  # raises what the damage is
            value, pos = read_uvarint(buf, pos)
            values.append(value)
        return np.array(values, dtype=np.uint64), pos
    out = np.zeros(count, dtype=np.uint64)
    low = (b & 0x7F).astype(np.uint64)
    for k in range(int(lengths.max())):
        has = lengths > k
        out[has] |= low[starts[has] + k] << np.uint64(7 * k)
    return out, pos + int(ends[-1]) + 1


def zigzag(v: np.ndarray) -> np.ndarray:
    """``(v << 1) ^ (v >> 63)`` as uint64 (same shape and memory order as ``v``), in one new array."""
    v = np.asarray(v, dtype=np.int64)
    out = np.left_shift(v, 1, out=np.empty_like(v))
    out ^= v >> 63
    return out.view(np.uint64)


def unzigzag(u: np.ndarray) -> np.ndarray:
    u = np.asarray(u, dtype=np.uint64)  # (u >> 1) ^ -(u & 1), both below 2 ** 63: viewed as int64, no casts
    out = np.right_shift(u, np.uint64(1), out=np.empty(u.shape, np.uint64)).view(np.int64)
    out ^= np.negative(np.bitwise_and(u, np.uint64(1), out=np.empty(u.shape, np.uint64)).view(np.int64))
    return out


def pack_uint64(values: np.ndarray, level: int = LEVEL) -> bytes:
    """Pack non-negative integers as zstd-compressed byte planes (small-value friendly; zstd at ``level``)."""
    u = np.ascontiguousarray(values, dtype=np.uint64).ravel()
    return _pack_planes(lambda: iter([u]), u.size, level)


def pack_zigzag_columns(v: np.ndarray, sparse: bool = False) -> bytes:
    """``pack_uint64(zigzag(v.T))`` of an int64 matrix ``v`` ``(rows, columns)`` (its columns one after the
    other), a few columns at a time: no whole-matrix temporaries beside the byte planes. ``sparse``: ``v`` is
    mostly zero (zstd's search of :func:`_compressor`)."""
    rows, cols = v.shape
    step = max(1, COLUMN_VALUES // max(rows, 1))
    return _pack_planes(lambda: (zigzag(np.ascontiguousarray(v[:, a:a + step].T)).ravel()
                                 for a in range(0, cols, step)), v.size, sparse=sparse)


def _pack_planes(chunks: Callable[[], Iterator[np.ndarray]], count: int, level: int = LEVEL,
                 sparse: bool = False) -> bytes:
    """The :func:`pack_uint64` stream of the ``count`` uint64 values ``chunks()`` yields (contiguous arrays, asked
    for twice: their largest, then their bytes): the low bytes of every value, plane by plane, zstd-packed
    (``sparse``: of a mostly-zero matrix, :func:`_compressor`)."""
    top = max((int(c.max()) for c in chunks() if c.size), default=0)
    nbytes = max(1, (top.bit_length() + 7) // 8)
    planes = np.empty((nbytes, count), dtype=np.uint8)
    pos = 0
    for c in chunks():
        planes[:, pos:pos + c.size] = c.view(np.uint8).reshape(-1, 8)[:, :nbytes].T
        pos += c.size
    body = _compressor(level, planes.nbytes, sparse).compress(planes)  # its buffer as it is (no bytes copy)
    return write_uvarint(count) + bytes([nbytes]) + body


def decompressor(dict_data: zstandard.ZstdCompressionDict | None = None) -> zstandard.ZstdDecompressor:
    """This thread's zstd decompressor (with ``dict_data``, one per dictionary): made once, not for each of a
    file's streams (about 9 us each: a seek reads a few of them; one is not safe across threads)."""
    made = getattr(_LOCAL, "unzstd", None)
    if made is None:
        made = _LOCAL.unzstd = {}
    key = None if dict_data is None else id(dict_data)
    d = made.get(key)
    if d is None:
        d = made[key] = zstandard.ZstdDecompressor() if dict_data is None else \
            zstandard.ZstdDecompressor(dict_data=dict_data)
    return d


def safe_zstd_decompress(data: bytes, limit: int, what: str) -> bytes:
    """zstd-decompress at most ``limit`` bytes; a frame claiming more is corrupt (FormatError), never a
    huge allocation."""
    try:
        size = zstandard.get_frame_parameters(data).content_size
    except zstandard.ZstdError as exc:
        raise FormatError(None, f"corrupted {what} ({exc})") from None
    if size != zstandard.CONTENTSIZE_UNKNOWN and size > limit:
        raise FormatError(None, f"corrupted {what} (claims {size} bytes, at most {limit} expected)")
    try:
        out = decompressor().decompress(data, max_output_size=limit)
    except zstandard.ZstdError as exc:
        raise FormatError(None, f"corrupted {what} ({exc})") from None
    return out


def zstd_capacity(size: int) -> int:
    """The most bytes a zstd frame of ``size`` bytes can hold: every block of at most 128 KiB costs at least its
    3-byte header, so a count claiming more than this is damage, whatever the frame says."""
    return (size // 3 + 1) << 17


def unpack_uint64(buf: bytes, count: int | None = None, *, at_most: int = MAX_COUNT) -> np.ndarray:
    """Inverse of :func:`pack_uint64`.

    ``count`` is the number of values the caller expects (from the header or an earlier section), else there
    are at most ``at_most``; a stream claiming anything else is a FormatError before anything is decompressed.
    """
    planes = _unpack_planes(buf, count, at_most)
    nbytes, n = planes.shape
    full = np.zeros((n, 8), dtype=np.uint8)
    full[:, :nbytes] = planes.T
    return full.view(np.uint64).ravel()


def unpack_zigzag_columns(buf: bytes, rows: int, cols: int) -> np.ndarray:
    """Inverse of :func:`pack_zigzag_columns`: the int64 matrix ``(rows, columns)``, equal to
    ``unzigzag(unpack_uint64(buf, rows * cols)).reshape(cols, rows).T``."""
    return unpack_zigzag_rows(buf, rows, cols, [(0, rows)])[0]


def unpack_zigzag_rows(buf: bytes, rows: int, cols: int, spans: list[tuple[int, int]]) -> list[np.ndarray]:
    """Rows ``[first, stop)`` of :func:`unpack_zigzag_columns`'s matrix for every span ``(first, stop)``, the
    stream decompressed once. The planes are joined, transposed and unzigzagged in the narrowest unsigned type
    that holds them, and widened once at the end (a few bytes per value moved instead of three passes of
    eight)."""
    return planes_rows(unpack_planes(buf, rows * cols), rows, cols, spans)


def unpack_planes(buf: bytes, count: int) -> np.ndarray:
    """The unpacked byte planes of a :func:`pack_zigzag_columns` stream of ``count`` values (what
    :func:`planes_rows` reads rows from: a reader may keep them)."""
    return _unpack_planes(buf, count, MAX_COUNT)


def planes_rows(planes: np.ndarray, rows: int, cols: int, spans: list[tuple[int, int]]) -> list[np.ndarray]:
    """:func:`unpack_zigzag_rows` from planes unpacked already (:func:`unpack_planes`)."""
    return [_columns(planes, rows, cols, a, b).T.astype(np.int64, order="C") for a, b in spans]


def unpack_zigzag_running(buf: bytes, rows: int, cols: int, a: int, b: int) -> np.ndarray:
    """Rows ``[a, b)`` ``(b - a, columns)`` int64 of the running sums down the columns of
    :func:`unpack_zigzag_columns`'s matrix (``np.cumsum(matrix, axis=0)[a:b]``, the same integers), summed in
    the stream's column order, where each column's values lie side by side (several times faster than down a
    row-major matrix)."""
    if a >= b:
        return np.zeros((0, cols), dtype=np.int64)
    v = _columns(_unpack_planes(buf, rows * cols, MAX_COUNT), rows, cols, 0, b).astype(np.int64)
    np.cumsum(v, axis=1, out=v)
    return np.ascontiguousarray(v[:, a:].T)


def _columns(planes: np.ndarray, rows: int, cols: int, a: int, b: int) -> np.ndarray:
    """Rows ``[a, b)`` of the matrix of unpacked ``planes``, column by column: ``(cols, b - a)`` signed integers,
    in the narrowest type that holds them."""
    nbytes = planes.shape[0]
    kind, signed = (np.uint8, np.int8) if nbytes == 1 else (np.uint16, np.int16) if nbytes == 2 \
        else (np.uint32, np.int32) if nbytes <= 4 else (np.uint64, np.int64)
    part = planes.reshape(nbytes, cols, rows)[:, :, a:b]
    u = part[0].astype(kind)
    for k in range(1, nbytes):
        u |= part[k].astype(kind) << kind(8 * k)
    # (u >> 1) ^ -(u & 1): below 2 ** (8 nbytes - 1) and 0 or -1, exact in the signed type of the same width
    return (u >> kind(1)).view(signed) ^ -(u & kind(1)).view(signed)


def _unpack_planes(buf: bytes, count: int | None, at_most: int) -> np.ndarray:
    """The byte planes ``(bytes per value, values)`` uint8 of a :func:`pack_uint64` stream, its claims checked
    (:func:`unpack_uint64`)."""
    n, pos = read_uvarint(buf, 0)
    if pos >= len(buf):
        raise FormatError(None, "truncated integer stream")
    if count is not None and n != count:
        raise FormatError(None, f"corrupted integer stream ({n} values where {count} are expected)")
    if n > at_most:
        raise FormatError(None, f"corrupted integer stream ({n} values, at most {at_most} expected)")
    nbytes = buf[pos]
    if not 1 <= nbytes <= 8:
        raise FormatError(None, "corrupted integer stream (bad byte width)")
    if n * nbytes > zstd_capacity(len(buf) - pos - 1):
        raise FormatError(None, f"corrupted integer stream ({n} values cannot fit in {len(buf)} bytes)")
    raw = safe_zstd_decompress(bytes(buf[pos + 1 :]), n * nbytes, "integer stream")
    if len(raw) != n * nbytes:
        raise FormatError(None, "corrupted integer stream (wrong length)")
    return np.frombuffer(raw, dtype=np.uint8).reshape(nbytes, n)
