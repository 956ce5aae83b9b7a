"""Helpers shared by the baseline codecs: the value matrix they work on, gaps, angle wrapping, float32 I/O.

Every baseline works on a ``(frames, columns)`` matrix of values:

* skeletal :class:`~mocapz.Motion`: the channel values in the file's own units, rotation channels
  unwrapped along time (no jumps of a full turn), so that interpolation and linear models see smooth
  curves. Decoders wrap rotation channels back into ``[-180, 180)`` degrees (``[-pi, pi)`` radians): the
  same rotations, written in the skeleton's own channels.
* :class:`~mocapz.MarkerMotion`: the marker coordinates ``x, y, z`` of every marker (``columns = 3 *
  markers``). Missing samples (gaps) are filled by linear interpolation in time for the codec's model,
  the gap mask is stored apart, and decoders put NaN back exactly where the original had gaps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mocapz.codecs.gaps import fill_linear, pack_mask, unpack_mask
from mocapz.errors import FormatError
from mocapz.format.entropy import read_uvarint, write_uvarint
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, Motion


@dataclass
class Values:
    """The matrix a baseline codes.

    Attributes:
        x: ``(frames, columns)`` float64, finite (gaps filled, angles unwrapped).
        gaps: ``(frames, markers)`` bool, True where a marker sample is missing; ``None`` for skeletons
            and for marker data without gaps.
        rotation: ``(columns,)`` bool, True for rotation channels (always False for markers).
        period: a full turn in the file's angle unit (360 or 2 pi); 0 for markers.
    """

    x: np.ndarray
    gaps: np.ndarray | None
    rotation: np.ndarray
    period: float


def values_of(motion: AnyMotion) -> Values:
    """The value matrix of a motion (see the module docstring)."""
    if isinstance(motion, Motion):
        sk = motion.skeleton
        rot = sk.rotation_columns()
        period = 360.0 if sk.angle_unit == "deg" else 2 * math.pi
        x = motion.channels.copy()
        if rot.any() and len(x) > 1:
            x[:, rot] = np.unwrap(x[:, rot], period=period, axis=0)
        return Values(x, None, rot, period)
    pos = motion.positions.reshape(motion.n_frames, 3 * motion.n_markers)
    missing = motion.missing
    gaps = missing if missing.any() else None
    x = fill_linear(pos, np.repeat(missing, 3, axis=1)) if gaps is not None else pos.copy()
    return Values(x, gaps, np.zeros(x.shape[1], dtype=bool), 0.0)


def layout_columns(header: ClipHeader) -> tuple[int, np.ndarray, float]:
    """Column count, rotation mask ``(columns,)`` and full-turn period of a clip."""
    return header.n_columns, header.rotation_mask, header.period


def finish(header: ClipHeader, x: np.ndarray, gaps: np.ndarray | None, round_decimals: bool) -> AnyMotion:
    """Decoded motion from a decoded value matrix ``(frames, columns)``.

    Skeletons: rotation channels wrapped into ``[-half turn, half turn)``; with ``round_decimals`` and a
    source whose decimals are known, every value is rounded to the largest of the source's decimal counts
    (the file's precision; the decoded motion then says so), else the decoded motion's decimals are
    unknown. Markers: NaN where ``gaps`` ``(frames, markers)`` is True.
    """
    frames = header.frames
    cols, rot, period = layout_columns(header)
    x = np.array(x, dtype=np.float64, copy=True).reshape(frames, cols)
    if header.skeleton is not None:
        if rot.any():
            half = period / 2
            x[:, rot] = np.mod(x[:, rot] + half, period) - half
        motion = header.motion(x)
        assert isinstance(motion, Motion)
        dec = header.decimals
        if round_decimals and dec is not None and len(dec):
            d = int(max(dec))
            motion.channels = np.round(motion.channels * 10.0**d) / 10.0**d
            motion.decimals = np.full(cols, d, dtype=np.int64)
        else:
            motion.decimals = None
        return motion
    pos = x.reshape(header.value_shape)
    if gaps is not None:
        pos = np.where(gaps[..., None], np.nan, pos)
    motion = header.motion(pos)
    motion.decimals = None
    return motion


# ---------------------------------------------------------------- sections
def gaps_bytes(gaps: np.ndarray) -> bytes:
    """The gap mask ``(frames, markers)`` as packed bits, zstd-coded."""
    return pack_mask(gaps)


def gaps_from(sections: dict[str, bytes], header: ClipHeader) -> np.ndarray | None:
    """The gap mask ``(frames, markers)`` stored by :func:`gaps_bytes`, or ``None``."""
    if "gaps" not in sections or header.skeleton is not None:
        return None
    return unpack_mask(sections["gaps"], (header.frames, len(header.labels)))


def f32_bytes(a: np.ndarray) -> bytes:
    """Little-endian float32 bytes of an array (row-major)."""
    return np.ascontiguousarray(a, dtype="<f4").tobytes()


def f32_array(data: bytes, shape: tuple[int, ...]) -> np.ndarray:
    """Inverse of :func:`f32_bytes` as float64, checking the size and that every value is finite (encoders
    write finite values only)."""
    n = math.prod(shape)
    if len(data) != 4 * n:
        raise FormatError(None, f"corrupted float32 block ({len(data)} bytes for {n} values)")
    values = np.frombuffer(data, dtype="<f4")
    if not np.isfinite(values).all():
        raise FormatError(None, "corrupted float32 block (values not finite)")
    return values.astype(np.float64).reshape(shape)


def uvarints(*values: int) -> bytes:
    return b"".join(write_uvarint(int(v)) for v in values)


def read_uvarints(data: bytes, count: int) -> tuple[list[int], int]:
    out, pos = [], 0
    for _ in range(count):
        v, pos = read_uvarint(data, pos)
        out.append(v)
    return out, pos
