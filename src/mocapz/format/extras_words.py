"""Word matrices: a ``(rows, cols)`` matrix of C3D words (what the file stores: an int16, or the 32 bits of a
float32 in the file's processor layout, held as int64) coded losslessly, and back. Used for the ``c3d.*``
sections of :mod:`mocapz.format.extras`.

A word matrix is one mode byte and a stream: the words as integers (int16 values; float32 words as
their integer value when every word is an integer-valued float that converts back to the same bits,
else as order-preserving integers of their bits), predicted by nothing, the previous row or the two
previous rows (first or second differences down each column), range coded (:func:`encode_int_matrix`);
or the little-endian words through xz, whichever is smallest; or (mode ``0x40``) a stepped matrix of
rounded columns (:mod:`mocapz.format.extras_precision`). Every decoder checks the sizes it is given against
the clip's header before it allocates.
"""

from __future__ import annotations

import lzma

import numpy as np

from mocapz.errors import FormatError
from mocapz.format.entropy import LIMIT, decode_int_matrix, encode_int_matrix
from mocapz.format.extras_precision import STEPPED, decode_stepped
from mocapz.model.c3d_extras import float_values, float_words

XZ_MEMORY = 1 << 26  # the most memory an xz stream here may ask of its decoder
MODE_INT, MODE_FLOAT_INT, MODE_BITS, MODE_XZ = 0, 1, 2, 3
# the largest word matrix (bytes) whose raw words are tried row by row through xz as well as column by column: a
# second of analog samples row by row packs smaller at times (a few blocks of the Eb015 trials, by 36 B), a whole
# clip's never did on a shared C3D, where it was the slowest candidate (0.66 s of markers_analogs.c3d's 2.1)
ROW_MAJOR_BYTES = 1 << 18


def _bad(what: str) -> FormatError:
    return FormatError(None, f"corrupted C3D extras ({what})")


def encode_words(words: np.ndarray, is_float: bool, processor: int) -> bytes:
    """A ``(rows, cols)`` int64 word matrix as the smallest of the codings of the module docstring.

    The mode byte: ``0x03`` / ``0x13`` the raw words row- / column-major through xz (``0x03`` tried up to
    :data:`ROW_MAJOR_BYTES`); else bits 0-1 the integer form (:data:`MODE_INT`, :data:`MODE_FLOAT_INT`,
    :data:`MODE_BITS`), bits 2-3 the prediction order, bits 4-5 the back end (0 range coder; 1 / 2: the integers
    column by column as 2 / 4 little-endian byte planes through xz).
    """
    w = np.asarray(words, dtype=np.int64)
    rows, cols = w.shape
    if w.size == 0:
        return bytes([MODE_INT])
    dtype = "<u4" if is_float else "<i2"
    xz_inputs = {MODE_XZ: w.astype(dtype).tobytes()} if w.size * (4 if is_float else 2) <= ROW_MAJOR_BYTES else {}
    xz_inputs[MODE_XZ | 1 << 4] = np.ascontiguousarray(w.T).astype(dtype).tobytes()
    options = []
    for mode, ints in _integer_forms(w, is_float, processor):
        for order in (0, 1, 2):
            residual = np.diff(ints, n=order, axis=0, prepend=np.zeros((order, cols), dtype=np.int64))
            if np.count_nonzero(np.abs(residual) >= LIMIT) * 10 < residual.size:  # else mostly escapes
                options.append(bytes([mode | order << 2]) + encode_int_matrix(residual))
            if order < 2:
                width = 2 if residual.min() >= -(1 << 15) and residual.max() < 1 << 15 else 4
                if width == 4 and (residual.min() < -(1 << 31) or residual.max() >= 1 << 31):
                    continue
                xz_inputs[mode | order << 2 | width // 2 << 4] = _planes(residual, width)
    options += [bytes([m]) + xz(raw) for m, raw in xz_inputs.items()]
    best = min(options, key=len)
    if best[0] in xz_inputs:  # the winner once more, at preset 9e
        best = min(best, bytes(best[:1]) + xz(xz_inputs[best[0]], extreme=True), key=len)
    return best


def _planes(ints: np.ndarray, width: int) -> bytes:
    """``(rows, cols)`` integers as ``width`` byte planes of the column-major little-endian words."""
    col_major = np.ascontiguousarray(ints.T).astype(f"<i{width}")
    return np.ascontiguousarray(col_major.view(np.uint8).reshape(-1, width).T).tobytes()


def _from_planes(raw: bytes, shape: tuple[int, int], width: int) -> np.ndarray:
    rows, cols = shape
    planes = np.frombuffer(raw, dtype=np.uint8).reshape(width, rows * cols)
    words = np.ascontiguousarray(planes.T).view(f"<i{width}").reshape(cols, rows)
    return words.T.astype(np.int64)


def _integer_forms(w: np.ndarray, is_float: bool, processor: int) -> list[tuple[int, np.ndarray]]:
    if not is_float:
        return [(MODE_INT, w)]
    forms = [(MODE_BITS, _ordered_bits(w, processor))]
    v = float_values(w, processor)
    with np.errstate(invalid="ignore"):
        ok = bool(np.isfinite(v).all() and (np.abs(v) < 2**31).all())
    if ok and np.array_equal(np.round(v), v):
        ints = v.astype(np.int64)
        if np.array_equal(float_words(ints.astype(np.float64), processor), w):
            forms.append((MODE_FLOAT_INT, ints))
    return forms


def _ordered_bits(w: np.ndarray, processor: int) -> np.ndarray:
    """float words as order-preserving int64 (DEC words: halves swapped first)."""
    u = w.astype(np.uint64) & np.uint64(0xFFFFFFFF)
    if processor == 85:
        u = ((u >> np.uint64(16)) | (u << np.uint64(16))) & np.uint64(0xFFFFFFFF)
    s = u.astype(np.int64)
    return np.where(s >= 1 << 31, (1 << 31) - 1 - s, s)


def _from_ordered_bits(s: np.ndarray, processor: int) -> np.ndarray:
    if s.size and (s.min() < -(1 << 31) or s.max() >= 1 << 31):
        raise _bad("float word out of range")
    u = np.where(s < 0, (1 << 31) - 1 - s, s).astype(np.uint64)
    if processor == 85:
        u = ((u >> np.uint64(16)) | (u << np.uint64(16))) & np.uint64(0xFFFFFFFF)
    return u.astype(np.int64)


def decode_words(data: bytes, shape: tuple[int, int], is_float: bool, processor: int,
                 stepped: bool = True) -> np.ndarray:
    """Inverse of :func:`encode_words` (and, if ``stepped``, of
    :func:`~mocapz.format.extras_precision.encode_stepped`), for the ``shape`` the header declares."""
    rows, cols = shape
    if not data:
        raise _bad("empty word stream")
    if data[0] == STEPPED and stepped:
        return decode_stepped(data, shape, is_float, processor,
                              lambda rest, part: decode_words(rest, part, is_float, processor, stepped=False))
    if rows * cols == 0:
        return np.zeros(shape, dtype=np.int64)
    mode, order, backend = data[0] & 3, data[0] >> 2 & 3, data[0] >> 4
    if mode == MODE_XZ and data[0] in (MODE_XZ, MODE_XZ | 1 << 4):
        size = rows * cols * (4 if is_float else 2)
        raw = unxz(data[1:], size, "word stream")
        if len(raw) != size:
            raise _bad("word stream of the wrong length")
        words = np.frombuffer(raw, dtype="<u4" if is_float else "<i2").astype(np.int64)
        return words.reshape(shape) if data[0] == MODE_XZ else words.reshape(cols, rows).T.copy()
    if order > 2 or backend > 2 or mode == MODE_XZ or (mode == MODE_INT) == is_float:
        raise _bad(f"word stream mode {data[0]}")
    if backend:
        size = rows * cols * 2 * backend
        raw = unxz(data[1:], size, "word planes")
        if len(raw) != size:
            raise _bad("word planes of the wrong length")
        ints = _from_planes(raw, shape, 2 * backend)
    else:
        ints = decode_int_matrix(data[1:], (rows, cols))
    for _ in range(order):
        ints = np.cumsum(ints, axis=0)
    if mode == MODE_INT:
        if ints.min() < -32768 or ints.max() > 32767:
            raise _bad("int16 word out of range")
        return ints
    if mode == MODE_BITS:
        return _from_ordered_bits(ints, processor)
    if np.abs(ints).max() >= 1 << 31:
        raise _bad("integer float word out of range")
    return float_words(ints.astype(np.float64), processor)


def xz(data: bytes, extreme: bool = False) -> bytes:
    """xz (preset 9, or 9e) with a dictionary no larger than the data: little memory on both sides."""
    size = max(1 << 12, 1 << max(len(data) - 1, 1).bit_length())
    preset = 9 | lzma.PRESET_EXTREME if extreme else 9
    filters = [{"id": lzma.FILTER_LZMA2, "preset": preset, "dict_size": min(size, 1 << 24)}]
    return lzma.compress(data, format=lzma.FORMAT_XZ, check=lzma.CHECK_NONE, filters=filters)


def unxz(data: bytes, limit: int, what: str) -> bytes:
    dec = lzma.LZMADecompressor(format=lzma.FORMAT_XZ, memlimit=XZ_MEMORY)
    try:
        out = dec.decompress(data, max_length=limit + 1)
    except lzma.LZMAError as exc:
        raise _bad(f"{what}: {exc}") from None
    if len(out) > limit or not dec.eof:
        raise _bad(f"{what}: longer than declared or truncated")
    return out
