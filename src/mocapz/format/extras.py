"""The C3D extras (:class:`~mocapz.model.c3d_extras.C3DExtras`) as container sections, coded losslessly
whatever codec codes the marker positions, and back.

Sections (names starting ``c3d.`` are reserved for this module; no codec writes them):

* ``c3d.file``: byte 1 (version), then an xz stream (preset 9e) of: uvarint length + JSON (processor, storage,
  scales, which points are markers and which tracks, track labels / kinds / units, counts), then
  uvarint length + bytes of the header, the gap before the parameter section, the parameter section and
  (after a presence byte) the bytes after the data;
* ``c3d.res`` residual words ``(frames, points)``, ``c3d.trk`` track words ``(frames, tracks * 3)``,
  ``c3d.ana`` analog words ``(frames * samples, channels)``: each a word matrix (:func:`encode_words`),
  exact; the last two, when the user names a precision for them, rounded and stepped
  (:mod:`mocapz.format.extras_precision`);
* ``c3d.fix``: uvarint length + zstd of the packed ``(frames, markers)`` mask, then a word matrix of the
  masked samples' x, y, z words.

A clip coded in blocks (:mod:`mocapz.blocking`) has its extras in the same blocks, so that a frame range
decodes only the analogs, residuals and tracks of its blocks: ``c3d.blk`` (uvarint frames per block, uvarint
block count, as :mod:`mocapz.format.blocks`), then ``c3d.res.<i>``, ``c3d.trk.<i>``, ``c3d.ana.<i>`` and
``c3d.fix.<i>`` for every block ``i`` (its frames' rows) instead of the four whole-clip sections.

Word matrices are :mod:`mocapz.format.extras_words`.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import zstandard

from mocapz.errors import FormatError
from mocapz.format.blocks import BlockIndex
from mocapz.format.entropy import read_uvarint, safe_zstd_decompress, write_uvarint
from mocapz.format.extras_precision import ExtrasPrecision, encode_stepped, quantised_extras
from mocapz.format.extras_words import decode_words, encode_words, unxz, xz
from mocapz.model.c3d_extras import C3DExtras
from mocapz.model.motion import AnyMotion, MarkerMotion

PREFIX = "c3d."
BLOCKS = PREFIX + "blk"  # the block index of extras coded in blocks
VERSION = 1
MAX_WORDS = 1 << 26  # most words (residual, track, analog) one clip's sections may hold: 512 MiB decoded
FRAME_PARAMS = ("POINT:FRAMES", "TRIAL:ACTUAL_START_FIELD", "TRIAL:ACTUAL_END_FIELD")
MAX_STATIC = 1 << 26  # most bytes of header, parameter section and trailing bytes


def _bad(what: str) -> FormatError:
    return FormatError(None, f"corrupted C3D extras ({what})")


# ----------------------------------------------------------------------------------------- sections
def encode_extras(extras: C3DExtras, precision: ExtrasPrecision | None = None,
                  block_frames: int = 0) -> dict[str, bytes]:
    """The ``c3d.*`` sections of ``extras``: exact, or with the analog channels and tracks rounded to
    ``precision`` (:mod:`mocapz.format.extras_precision`); the frames' words in blocks of ``block_frames``
    frames when the clip has two or more (0: one block), as the codec's blocks (:mod:`mocapz.blocking`)."""
    fmt = (extras.is_float, extras.processor)
    steps: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
    if precision is not None:
        extras, ana_steps, trk_steps = quantised_extras(extras, precision)
        steps = (ana_steps, trk_steps)
    info = {"processor": extras.processor, "float": extras.is_float, "scales": extras.scales.tolist(),
            "markers": extras.marker_index.tolist(), "tracks": extras.track_index.tolist(),
            "track_labels": extras.track_labels, "track_kinds": extras.track_kinds,
            "track_units": extras.track_units, "samples": extras.samples, "channels": extras.channels,
            "frame_params": {k: list(v) for k, v in extras.frame_params.items()}}
    blob = json.dumps(info, separators=(",", ":")).encode()
    parts = [blob, extras.header, extras.gap, extras.params]
    static = b"".join(write_uvarint(len(p)) + p for p in parts)
    static += b"\x00" if extras.tail is None else b"\x01" + write_uvarint(len(extras.tail)) + extras.tail
    out = {PREFIX + "file": bytes([VERSION]) + xz(static, extreme=True)}
    index = BlockIndex(extras.frames, block_frames) if block_frames > 0 else None
    if index is None or index.count < 2:
        return out | _frame_sections(extras, steps, fmt, "")
    out[BLOCKS] = write_uvarint(block_frames) + write_uvarint(index.count)
    for i in range(index.count):
        out |= _frame_sections(extras.rows(*index.bounds(i)), steps, fmt, f".{i}")
    return out


def _frame_sections(extras: C3DExtras, steps: tuple[np.ndarray | None, np.ndarray | None], fmt: tuple[bool, int],
                    suffix: str) -> dict[str, bytes]:
    """The word sections of the frames ``extras`` holds, named ``c3d.<key><suffix>``."""
    mask = np.packbits(extras.fix_mask.ravel())
    packed = zstandard.ZstdCompressor(level=19).compress(mask.tobytes())
    f = extras.frames
    return {
        f"{PREFIX}res{suffix}": encode_words(extras.residual_words, *fmt),
        f"{PREFIX}trk{suffix}": _words(extras.track_words.reshape(f, 3 * extras.track_index.size), steps[1], fmt),
        f"{PREFIX}ana{suffix}": _words(extras.analog_words, steps[0], fmt),
        f"{PREFIX}fix{suffix}": write_uvarint(len(packed)) + packed
        + encode_words(extras.fix_words[extras.fix_mask], *fmt),
    }


def _words(words: np.ndarray, steps: np.ndarray | None, fmt: tuple[bool, int]) -> bytes:
    """A word matrix: stepped where ``steps`` rounded columns, unless coding the rounded words as they are
    (:func:`encode_words`) is smaller."""
    plain = encode_words(words, *fmt)
    if steps is None or not (steps > 0).any():
        return plain
    return min(plain, encode_stepped(words, steps, *fmt, lambda rest: encode_words(rest, *fmt)), key=len)


def sections_of(motion: AnyMotion, precision: ExtrasPrecision | None = None,
                block_frames: int = 0) -> dict[str, bytes]:
    """The ``c3d.*`` sections of a motion read from a C3D file (``{}`` for any other motion, and for extras
    that describe another clip: another frame or marker count); analogs and tracks exact unless
    ``precision`` names one; in blocks of ``block_frames`` (:func:`encode_extras`)."""
    extras = motion.metadata.get("c3d") if isinstance(motion, MarkerMotion) else None
    if isinstance(extras, C3DExtras) and extras.matches(motion.n_frames, motion.n_markers):
        words = extras.frames * (4 * extras.points + extras.samples * extras.channels)
        if words > MAX_WORDS:
            raise FormatError(motion.metadata.get("path"), f"C3D data of {words} words: mocapz keeps at most "
                                                          f"{MAX_WORDS} (cut the clip with --frames)")
        return encode_extras(extras, precision, block_frames)
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


def decode_extras(sections: dict[str, bytes], frames: int, markers: int, start: int = 0,
                  stop: int | None = None) -> C3DExtras:
    """Inverse of :func:`encode_extras` for a clip of ``frames`` frames and ``markers`` markers: the extras of
    frames ``[start, stop)`` (of the whole clip by default), decoding only the blocks they lie in."""
    stop = frames if stop is None else stop
    if PREFIX + "file" not in sections:
        raise _bad(f"section {PREFIX}file missing")
    file = sections[PREFIX + "file"]
    if not file or file[0] != VERSION:
        raise _bad("unknown version")
    static = unxz(file[1:], MAX_STATIC, "file section")
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
    shape = (len(info["scales"]), len(info["tracks"]), int(info["samples"]), int(info["channels"]), markers)
    if len(parts[1]) != 512:
        raise _bad("header is not 512 bytes")
    if frames * (4 * shape[0] + shape[2] * shape[3]) > MAX_WORDS:
        raise _bad("implausible sizes")
    origin, words = _frames_words(sections, frames, start, stop, shape, fmt)
    res, trk, ana, mask, fix = words
    extras = C3DExtras(header=parts[1], gap=parts[2], params=parts[3], tail=tail, processor=fmt[1], is_float=fmt[0],
                       scales=np.asarray(info["scales"], dtype=np.float64),
                       marker_index=np.asarray(info["markers"], dtype=np.int64),
                       track_index=np.asarray(info["tracks"], dtype=np.int64),
                       track_labels=list(info["track_labels"]), track_kinds=list(info["track_kinds"]),
                       track_units=list(info["track_units"]), residual_words=res, track_words=trk,
                       fix_mask=mask, fix_words=fix, analog_words=ana, samples=shape[2],
                       frame_params={k: (int(v[0]), int(v[1]), int(v[2])) for k, v in info["frame_params"].items()})
    return extras.slice(start - origin, stop - origin, origin=origin)


Words = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _frames_words(sections: dict[str, bytes], frames: int, start: int, stop: int,
                  shape: tuple[int, int, int, int, int], fmt: tuple[bool, int]) -> tuple[int, Words]:
    """``(the first frame decoded, (residual, track, analog words, fix mask, fix words))`` of the blocks
    holding frames ``[start, stop)``, or of the whole clip when it is in one block."""
    if BLOCKS not in sections:
        return 0, _words_of(sections, "", frames, shape, fmt)
    block_frames, pos = read_uvarint(sections[BLOCKS], 0)
    count, pos = read_uvarint(sections[BLOCKS], pos)
    index = BlockIndex(frames, block_frames) if 1 <= block_frames <= frames else None
    if pos != len(sections[BLOCKS]) or index is None or index.count != count or count < 2:
        raise _bad("block index")
    covering = index.covering(start, stop) if start < stop else range(index.block_of(start), index.block_of(start) + 1)
    pieces = [_words_of(sections, f".{i}", index.bounds(i)[1] - index.bounds(i)[0], shape, fmt) for i in covering]
    joined = tuple(np.concatenate([p[k] for p in pieces]) for k in range(5))
    return index.bounds(covering[0])[0], joined  # type: ignore[return-value]


def _words_of(sections: dict[str, bytes], suffix: str, frames: int, shape: tuple[int, int, int, int, int],
              fmt: tuple[bool, int]) -> Words:
    """The words of one block (``suffix`` ``.<i>``) or of the whole clip (``""``) of ``frames`` frames."""
    n_points, n_tracks, s, c, markers = shape
    names = [f"{PREFIX}{key}{suffix}" for key in ("res", "trk", "ana", "fix")]
    for name in names:
        if name not in sections:
            raise _bad(f"section {name} missing")
    res = decode_words(sections[names[0]], (frames, n_points), *fmt)
    trk = decode_words(sections[names[1]], (frames, 3 * n_tracks), *fmt).reshape(frames, n_tracks, 3)
    ana = decode_words(sections[names[2]], (frames * s, c), *fmt)
    mask, fix = _fix(sections[names[3]], frames, markers, fmt)
    return res, trk, ana, mask, fix


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
