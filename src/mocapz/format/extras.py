"""The C3D extras (:class:`~mocapz.model.c3d_extras.C3DExtras`) as container sections, coded losslessly
whatever codec codes the marker positions, and back.

Sections (names starting ``c3d.`` are reserved for this module; no codec writes them):

* ``c3d.file``: byte 1 (version), then an xz stream (preset 9e) of: uvarint length + JSON (processor, storage,
  scales, which points are markers and which tracks, track labels / kinds / units, counts), then
  uvarint length + bytes of the header, the gap before the parameter section, the parameter section and
  (after a presence byte) the bytes after the data;
* ``c3d.res`` residual words ``(frames, points)``, ``c3d.trk`` track words ``(frames, tracks * 3)``,
  ``c3d.ana`` analog words ``(frames * samples, channels)``: each a word matrix (:func:`encode_words`);
* ``c3d.fix``: uvarint length + zstd of the packed ``(frames, markers)`` mask, then a word matrix of the
  masked samples' x, y, z words.

A word matrix is one mode byte and a stream: the words as integers (int16 values; float32 words as
their integer value when every word is an integer-valued float that converts back to the same bits,
else as order-preserving integers of their bits), predicted by nothing, the previous row or the two
previous rows (first or second differences down each column), range coded (:func:`encode_int_matrix`);
or the little-endian words through xz, whichever is smallest. Every decoder checks the sizes it is
given against the clip's header before it allocates.
"""

from __future__ import annotations

import json
import lzma
from typing import Any

import numpy as np
import zstandard

from mocapz.errors import FormatError
from mocapz.format.entropy import (
    LIMIT,
    decode_int_matrix,
    encode_int_matrix,
    read_uvarint,
    safe_zstd_decompress,
    write_uvarint,
)
from mocapz.model.c3d_extras import C3DExtras, float_values, float_words
from mocapz.model.motion import AnyMotion, MarkerMotion

PREFIX = "c3d."
VERSION = 1
MAX_WORDS = 1 << 26  # most words (residual, track, analog) one clip's sections may hold: 512 MiB decoded
FRAME_PARAMS = ("POINT:FRAMES", "TRIAL:ACTUAL_START_FIELD", "TRIAL:ACTUAL_END_FIELD")
MAX_STATIC = 1 << 26  # most bytes of header, parameter section and trailing bytes
XZ_MEMORY = 1 << 26  # the most memory an xz stream here may ask of its decoder
MODE_INT, MODE_FLOAT_INT, MODE_BITS, MODE_XZ = 0, 1, 2, 3


def _bad(what: str) -> FormatError:
    return FormatError(None, f"corrupted C3D extras ({what})")


# ----------------------------------------------------------------------------------------- word matrices
def encode_words(words: np.ndarray, is_float: bool, processor: int) -> bytes:
    """A ``(rows, cols)`` int64 word matrix as the smallest of the codings of the module docstring.

    The mode byte: ``0x03`` / ``0x13`` the raw words row- / column-major through xz; else bits 0-1 the
    integer form (:data:`MODE_INT`, :data:`MODE_FLOAT_INT`, :data:`MODE_BITS`), bits 2-3 the prediction
    order, bits 4-5 the back end (0 range coder; 1 / 2: the integers column by column as 2 / 4
    little-endian byte planes through xz).
    """
    w = np.asarray(words, dtype=np.int64)
    rows, cols = w.shape
    if w.size == 0:
        return bytes([MODE_INT])
    dtype = "<u4" if is_float else "<i2"
    xz_inputs = {MODE_XZ: w.astype(dtype).tobytes(),
                 MODE_XZ | 1 << 4: np.ascontiguousarray(w.T).astype(dtype).tobytes()}
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
    options += [bytes([m]) + _xz(raw) for m, raw in xz_inputs.items()]
    best = min(options, key=len)
    if best[0] in xz_inputs:  # the winner once more, at preset 9e
        best = min(best, bytes(best[:1]) + _xz(xz_inputs[best[0]], extreme=True), key=len)
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


def decode_words(data: bytes, shape: tuple[int, int], is_float: bool, processor: int) -> np.ndarray:
    """Inverse of :func:`encode_words`, for the ``shape`` the header declares."""
    rows, cols = shape
    if not data:
        raise _bad("empty word stream")
    if rows * cols == 0:
        return np.zeros(shape, dtype=np.int64)
    mode, order, backend = data[0] & 3, data[0] >> 2 & 3, data[0] >> 4
    if mode == MODE_XZ and data[0] in (MODE_XZ, MODE_XZ | 1 << 4):
        size = rows * cols * (4 if is_float else 2)
        raw = _unxz(data[1:], size, "word stream")
        if len(raw) != size:
            raise _bad("word stream of the wrong length")
        words = np.frombuffer(raw, dtype="<u4" if is_float else "<i2").astype(np.int64)
        return words.reshape(shape) if data[0] == MODE_XZ else words.reshape(cols, rows).T.copy()
    if order > 2 or backend > 2 or mode == MODE_XZ or (mode == MODE_INT) == is_float:
        raise _bad(f"word stream mode {data[0]}")
    if backend:
        size = rows * cols * 2 * backend
        raw = _unxz(data[1:], size, "word planes")
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


def _xz(data: bytes, extreme: bool = False) -> bytes:
    """xz (preset 9, or 9e) with a dictionary no larger than the data: little memory on both sides."""
    size = max(1 << 12, 1 << max(len(data) - 1, 1).bit_length())
    preset = 9 | lzma.PRESET_EXTREME if extreme else 9
    filters = [{"id": lzma.FILTER_LZMA2, "preset": preset, "dict_size": min(size, 1 << 24)}]
    return lzma.compress(data, format=lzma.FORMAT_XZ, check=lzma.CHECK_NONE, filters=filters)


def _unxz(data: bytes, limit: int, what: str) -> bytes:
    dec = lzma.LZMADecompressor(format=lzma.FORMAT_XZ, memlimit=XZ_MEMORY)
    try:
        out = dec.decompress(data, max_length=limit + 1)
    except lzma.LZMAError as exc:
        raise _bad(f"{what}: {exc}") from None
    if len(out) > limit or not dec.eof:
        raise _bad(f"{what}: longer than declared or truncated")
    return out


# ----------------------------------------------------------------------------------------- sections
def encode_extras(extras: C3DExtras) -> dict[str, bytes]:
    """The ``c3d.*`` sections of ``extras``."""
    fmt = (extras.is_float, extras.processor)
    info = {"processor": extras.processor, "float": extras.is_float, "scales": extras.scales.tolist(),
            "markers": extras.marker_index.tolist(), "tracks": extras.track_index.tolist(),
            "track_labels": extras.track_labels, "track_kinds": extras.track_kinds,
            "track_units": extras.track_units, "samples": extras.samples, "channels": extras.channels,
            "frame_params": {k: list(v) for k, v in extras.frame_params.items()}}
    blob = json.dumps(info, separators=(",", ":")).encode()
    parts = [blob, extras.header, extras.gap, extras.params]
    static = b"".join(write_uvarint(len(p)) + p for p in parts)
    static += b"\x00" if extras.tail is None else b"\x01" + write_uvarint(len(extras.tail)) + extras.tail
    mask = np.packbits(extras.fix_mask.ravel())
    packed = zstandard.ZstdCompressor(level=19).compress(mask.tobytes())
    f = extras.frames
    return {
        PREFIX + "file": bytes([VERSION]) + _xz(static, extreme=True),
        PREFIX + "res": encode_words(extras.residual_words, *fmt),
        PREFIX + "trk": encode_words(extras.track_words.reshape(f, 3 * extras.track_index.size), *fmt),
        PREFIX + "ana": encode_words(extras.analog_words, *fmt),
        PREFIX + "fix": write_uvarint(len(packed)) + packed + encode_words(extras.fix_words[extras.fix_mask], *fmt),
    }


def sections_of(motion: AnyMotion) -> dict[str, bytes]:
    """The ``c3d.*`` sections of a motion read from a C3D file (``{}`` for any other motion, and for extras
    that describe another clip: another frame or marker count)."""
    extras = motion.metadata.get("c3d") if isinstance(motion, MarkerMotion) else None
    if isinstance(extras, C3DExtras) and extras.matches(motion.n_frames, motion.n_markers):
        words = extras.frames * (4 * extras.points + extras.samples * extras.channels)
        if words > MAX_WORDS:
            raise FormatError(motion.metadata.get("path"), f"C3D data of {words} words: mocapz keeps at most "
                                                          f"{MAX_WORDS} (cut the clip with --frames)")
        return encode_extras(extras)
    return {}


def attach(motion: AnyMotion, sections: dict[str, bytes]) -> AnyMotion:
    """Put the extras coded in ``sections`` (the ``c3d.*`` ones, if any) into the decoded ``motion``."""
    if not sections:
        return motion
    if not isinstance(motion, MarkerMotion):
        raise _bad("C3D sections in a skeletal clip")
    motion.metadata["c3d"] = decode_extras(sections, motion.n_frames, motion.n_markers)
    return motion


def split_sections(sections: dict[str, bytes]) -> tuple[dict[str, bytes], dict[str, bytes]]:
    """``(the codec's sections, the c3d.* sections)``."""
    mine = {k: v for k, v in sections.items() if k.startswith(PREFIX)}
    return {k: v for k, v in sections.items() if not k.startswith(PREFIX)}, mine


def decode_extras(sections: dict[str, bytes], frames: int, markers: int) -> C3DExtras:
    """Inverse of :func:`encode_extras` for a clip of ``frames`` frames and ``markers`` markers."""
    for name in ("file", "res", "trk", "ana", "fix"):
        if PREFIX + name not in sections:
            raise _bad(f"section {PREFIX + name} missing")
    file = sections[PREFIX + "file"]
    if not file or file[0] != VERSION:
        raise _bad("unknown version")
    static = _unxz(file[1:], MAX_STATIC, "file section")
    pos, parts = 0, []
    for _ in range(4):
        n, pos = read_uvarint(static, pos)
        parts.append(static[pos:pos + n])
        pos += n
        if len(parts[-1]) != n:
            raise _bad("truncated file section")
    tail: bytes | None = None
    if pos >= len(static) or static[pos] not in (0, 1):
        raise _bad("trailing bytes flag")
    if static[pos] == 1:
        n, pos = read_uvarint(static, pos + 1)
        tail = static[pos:pos + n]
        pos += n
    else:
        pos += 1
    if pos != len(static):
        raise _bad("file section length")
    info = _info(parts[0], parts[3], markers)
    fmt = (bool(info["float"]), int(info["processor"]))
    n_points, n_tracks = len(info["scales"]), len(info["tracks"])
    s, c = int(info["samples"]), int(info["channels"])
    if len(parts[1]) != 512:
        raise _bad("header is not 512 bytes")
    if frames * (4 * n_points + s * c) > MAX_WORDS:
        raise _bad("implausible sizes")
    res = decode_words(sections[PREFIX + "res"], (frames, n_points), *fmt)
    trk = decode_words(sections[PREFIX + "trk"], (frames, 3 * n_tracks), *fmt).reshape(frames, n_tracks, 3)
    ana = decode_words(sections[PREFIX + "ana"], (frames * s, c), *fmt)
    mask, fix = _fix(sections[PREFIX + "fix"], frames, markers, fmt)
    return C3DExtras(header=parts[1], gap=parts[2], params=parts[3], tail=tail, processor=fmt[1], is_float=fmt[0],
                     scales=np.asarray(info["scales"], dtype=np.float64),
                     marker_index=np.asarray(info["markers"], dtype=np.int64),
                     track_index=np.asarray(info["tracks"], dtype=np.int64),
                     track_labels=list(info["track_labels"]), track_kinds=list(info["track_kinds"]),
                     track_units=list(info["track_units"]), residual_words=res, track_words=trk,
                     fix_mask=mask, fix_words=fix, analog_words=ana, samples=s,
                     frame_params={k: (int(v[0]), int(v[1]), int(v[2])) for k, v in info["frame_params"].items()})


def _fix(data: bytes, frames: int, markers: int, fmt: tuple[bool, int]) -> tuple[np.ndarray, np.ndarray]:
    n, pos = read_uvarint(data, 0)
    if pos + n > len(data):
        raise _bad("truncated fix section")
    size = -(-frames * markers // 8)
    packed = safe_zstd_decompress(bytes(data[pos:pos + n]), size, "C3D fix mask")
    if len(packed) != size:
        raise _bad("fix mask of the wrong length")
    mask = np.unpackbits(np.frombuffer(packed, dtype=np.uint8))[:frames * markers].astype(bool).reshape(frames, markers)
    words = np.zeros((frames, markers, 3), dtype=np.int64)
    words[mask] = decode_words(bytes(data[pos + n:]), (int(mask.sum()), 3), *fmt)
    return mask, words


def _info(blob: bytes, params: bytes, markers: int) -> dict[str, Any]:
    """The JSON of the file section, every field checked."""
    try:
        info = json.loads(blob)
    except (ValueError, UnicodeDecodeError):
        raise _bad("JSON") from None
    if not isinstance(info, dict):
        raise _bad("JSON")
    if info.get("processor") not in (84, 85, 86) or not isinstance(info.get("float"), bool):
        raise _bad("storage")
    scales = info.get("scales")
    if not isinstance(scales, list) or len(scales) > 65535 or not all(
            isinstance(x, int | float) and not isinstance(x, bool) and np.isfinite(x) for x in scales):
        raise _bad("scales")
    n = len(scales)
    m, t = info.get("markers"), info.get("tracks")
    if not (isinstance(m, list) and isinstance(t, list) and all(type(i) is int for i in m + t)):
        raise _bad("point indices")
    if len(m) != markers or sorted(m + t) != list(range(n)):
        raise _bad("point indices do not cover the points")
    for key in ("track_labels", "track_kinds", "track_units"):
        v = info.get(key)
        if not isinstance(v, list) or len(v) != len(t) or not all(isinstance(x, str) for x in v):
            raise _bad(key)
    for key in ("samples", "channels"):
        if type(info.get(key)) is not int or not 0 <= info[key] <= 65535:
            raise _bad(key)
    fp = info.get("frame_params")
    if not isinstance(fp, dict) or not all(
            k in FRAME_PARAMS and isinstance(v, list) and len(v) == 3 and all(type(x) is int for x in v)
            and v[1] in (2, 4) and 1 <= v[2] <= 65535 and 0 <= v[0] <= len(params) - v[1] * min(v[2], 2)
            for k, v in fp.items()):
        raise _bad("frame_params")
    return info
