"""What a C3D file holds besides its marker positions, kept so that the file can be written back in its
own storage: :class:`C3DExtras`, referenced from ``MarkerMotion.metadata["c3d"]``.

A C3D data section stores, for every frame, four words per point (x, y, z and a residual / camera-mask
word) and then the analog samples; a word is an int16 (integer storage, ``POINT:SCALE > 0``) or a
float32 (Intel, DEC or big-endian MIPS layout). The reader (:mod:`mocapz.io.c3d_raw`) puts the marker
positions in the :class:`~mocapz.model.motion.MarkerMotion` and everything else here, as the raw words
the file stores (so that it comes back bit for bit):

* the 512-byte header, the bytes between it and the parameter section, the parameter section itself
  (every group and parameter, unknown ones too, verbatim) and the bytes after the data;
* the residual word of every point sample, the x, y, z words of the points that are not marker
  positions (Plug-in-Gait angles, forces, moments, powers: *tracks*, with their own labels and units),
  the analog samples;
* the x, y, z words of the marker samples the positions cannot give back (missing samples, whose
  coordinates need not be 0; values a float conversion would not return bit for bit).

Words are held as int64: the int16 value (integer storage) or the 32 bits of the float as the file's
byte order reads them as an unsigned integer (float storage). Only :mod:`numpy` here: the model knows no
file or container code.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field, replace

import numpy as np

PROCESSOR_ORDER = {84: "<", 85: "<", 86: ">"}  # Intel, DEC, SGI/MIPS
#: the POINT lists naming points that are not marker positions, and the parameter giving their unit
#: (a file's POINT:TYPE_GROUPS may name more: pairs of a list and its unit prefix)
TRACK_UNIT_PARAMS = {"ANGLES": "ANGLE_UNITS", "FORCES": "FORCE_UNITS", "MOMENTS": "MOMENT_UNITS",
                     "POWERS": "POWER_UNITS", "REACTIONS": "REACTION_UNITS", "SCALARS": "SCALAR_UNITS"}


def word_dtype(processor: int, is_float: bool) -> np.dtype:
    """The numpy dtype of one stored word: ``int16`` or ``uint32`` (float bits) in the processor's order."""
    return np.dtype(f"{PROCESSOR_ORDER[processor]}{'u4' if is_float else 'i2'}")


def float_values(words: np.ndarray, processor: int) -> np.ndarray:
    """float64 values of float32 words (any shape; the uint32 bits as :func:`word_dtype` reads them).

    DEC (85): the two 16-bit halves swapped and the exponent 2 higher than IEEE; a zero exponent byte
    reads as 0 (as ezc3d and :func:`mocapz.io.c3d_checks.decode_float32` read them).
    """
    w = np.asarray(words, dtype=np.int64).astype(np.uint32)
    if processor == 85:
        w = (w >> np.uint32(16)) | (w << np.uint32(16))
        top = w >> np.uint32(24)
        w = np.where(top > 0, w - np.uint32(1 << 24), w & np.uint32(0x00FFFFFF))
    with np.errstate(invalid="ignore"):
        return w.astype(np.uint32).view(np.float32).astype(np.float64)


def float_words(values: np.ndarray, processor: int) -> np.ndarray:
    """Inverse of :func:`float_values` for float32-representable values: int64 words (NaN as 0)."""
    with np.errstate(invalid="ignore", over="ignore"):
        f = np.where(np.isfinite(values), values, 0.0).astype(np.float32)
    w = f.view(np.uint32).astype(np.uint32)
    if processor == 85:
        top = w >> np.uint32(24)
        w = np.where((top > 0) & (top < 255), w + np.uint32(1 << 24), w)
        w = (w >> np.uint32(16)) | (w << np.uint32(16))
    return w.astype(np.int64)


@dataclass
class C3DExtras:
    """Everything of a C3D file but its marker positions (see the module docstring).

    Attributes:
        header: the 512-byte header, as stored (frame numbers patched by :meth:`slice`).
        gap: bytes between the header and the parameter section (usually none).
        params: the parameter section, every block up to the data, verbatim.
        tail: bytes after the data section, or ``None`` (after :meth:`slice`): pad to a 512-byte block.
        processor: 84 Intel, 85 DEC, 86 SGI/MIPS.
        is_float: float32 storage (else int16 scaled by ``scales``).
        scales: ``(points,)`` float64 ``|POINT:SCALE|`` of every point (integer storage).
        marker_index: ``(markers,)`` position of each marker of the motion in the file's POINT block.
        track_index: ``(tracks,)`` position of each model-output point in the POINT block.
        track_labels, track_kinds, track_units: per track: label, list it is named in (``"ANGLES"``...)
            and unit (``"deg"``, ``"N"``, ``"Nmm"``...).
        residual_words: ``(frames, points)`` the fourth word of every point sample.
        track_words: ``(frames, tracks, 3)`` the x, y, z words of the tracks.
        fix_mask: ``(frames, markers)`` True where the marker's stored words are ``fix_words``.
        fix_words: ``(frames, markers, 3)`` stored x, y, z words where ``fix_mask`` (0 elsewhere).
        analog_words: ``(frames * samples, channels)`` the analog samples.
        samples: analog samples per point frame.
        frame_params: where the parameters that count frames hold their values in ``params``:
            ``{"POINT:FRAMES" / "TRIAL:ACTUAL_START_FIELD" / "TRIAL:ACTUAL_END_FIELD": (byte offset, kind
            2 int16 or 4 float, number of values)}``, patched by :meth:`slice`.
        analog_scales: ``(channels,)`` float64 ``|ANALOG:SCALE * ANALOG:GEN_SCALE|``, the analog unit of one
            stored number per channel, and analog_labels: ANALOG:LABELS, ``(channels,)``; both from the
            file's parameters by the reader (``None`` for extras decoded from a ``.mcz``: they are needed
            only to apply an analog precision, :mod:`mocapz.format.extras_precision`).
    """

    header: bytes
    gap: bytes
    params: bytes
    tail: bytes | None
    processor: int
    is_float: bool
    scales: np.ndarray
    marker_index: np.ndarray
    track_index: np.ndarray
    track_labels: list[str]
    track_kinds: list[str]
    track_units: list[str]
    residual_words: np.ndarray
    track_words: np.ndarray
    fix_mask: np.ndarray
    fix_words: np.ndarray
    analog_words: np.ndarray
    samples: int
    frame_params: dict[str, tuple[int, int, int]] = field(default_factory=dict)
    analog_scales: np.ndarray | None = None
    analog_labels: list[str] | None = None

    # ------------------------------------------------------------------ sizes
    @property
    def frames(self) -> int:
        return int(self.residual_words.shape[0])

    @property
    def points(self) -> int:
        return int(self.residual_words.shape[1])

    @property
    def channels(self) -> int:
        return int(self.analog_words.shape[1])

    @property
    def dtype(self) -> np.dtype:
        return word_dtype(self.processor, self.is_float)

    @property
    def quantum(self) -> float | None:
        """The step of integer storage when every marker has the same scale, else ``None``."""
        if self.is_float or self.scales.size == 0:
            return None
        s = self.scales[self.marker_index] if self.marker_index.size else self.scales
        return float(s[0]) if np.all(s == s[0]) and s[0] > 0 else None

    def matches(self, frames: int, markers: int) -> bool:
        """Whether these extras describe a motion of ``frames`` frames and ``markers`` markers."""
        return self.frames == frames and self.marker_index.size == markers

    # ------------------------------------------------------------------ values
    def values(self, words: np.ndarray, index: np.ndarray) -> np.ndarray:
        """float64 values of point words ``(..., len(index))`` / ``(..., len(index), 3)``."""
        if self.is_float:
            return float_values(words, self.processor)
        s = self.scales[index]
        return np.asarray(words, dtype=np.float64) * (s[:, None] if words.ndim == 3 else s)

    def words(self, values: np.ndarray, index: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`values` (int16 storage: rounded to the scale and clipped); NaN gives 0."""
        if self.is_float:
            return float_words(values, self.processor)
        s = self.scales[index]
        s = np.where((s > 0) & np.isfinite(s), s, 1.0)  # a scale of 0: the stored words are kept (fix_words)
        s = s[:, None] if values.ndim == 3 else s
        with np.errstate(invalid="ignore", over="ignore"):
            q = np.round(np.where(np.isfinite(values), values, 0.0) / s)
        return np.nan_to_num(np.clip(q, -32768, 32767)).astype(np.int64)

    def residual_values(self) -> np.ndarray:
        """``(frames, points)`` the residual words as numbers (negative: the sample is missing)."""
        if self.is_float:
            return float_values(self.residual_words, self.processor)
        return self.residual_words.astype(np.float64)

    def track_values(self) -> np.ndarray:
        """``(frames, tracks, 3)`` float64 model outputs in ``track_units``, NaN where missing."""
        vals = self.values(self.track_words, self.track_index)
        gone = self.residual_values()[:, self.track_index] < 0
        vals[gone | ~np.isfinite(vals).all(axis=2)] = np.nan
        return vals

    def analog_values(self) -> np.ndarray:
        """``(frames * samples, channels)`` the stored analog numbers (before ANALOG:SCALE / OFFSET)."""
        if self.is_float:
            return float_values(self.analog_words, self.processor)
        return self.analog_words.astype(np.float64)

    # ------------------------------------------------------------------ frames
    def _get(self, where: tuple[int, int, int]) -> int:
        """A frame number stored at ``where`` (int16 words read unsigned, low word first: Vicon's 32-bit
        TRIAL fields; or a float)."""
        at, kind, count = where
        if kind == 4:
            return int(float_values(np.frombuffer(self.params[at:at + 4], dtype=word_dtype(self.processor, True)),
                                    self.processor)[0])
        words = struct.unpack(f"{PROCESSOR_ORDER[self.processor]}{min(count, 2)}H",
                              self.params[at:at + 2 * min(count, 2)])
        return int(words[0] + (words[1] << 16 if len(words) > 1 else 0))

    def _put(self, params: bytearray, where: tuple[int, int, int], value: int) -> None:
        """Store frame number ``value`` at ``where`` (see :meth:`_get`)."""
        at, kind, count = where
        value = max(int(value), 0)
        if kind == 4:
            params[at:at + 4] = float_words(np.array([float(value)]), self.processor).astype(
                word_dtype(self.processor, True)).tobytes()
        elif count >= 2:
            struct.pack_into(f"{PROCESSOR_ORDER[self.processor]}HH", params, at, value & 0xFFFF, value >> 16 & 0xFFFF)
        else:
            struct.pack_into(f"{PROCESSOR_ORDER[self.processor]}H", params, at, value & 0xFFFF)

    def rows(self, start: int, stop: int) -> C3DExtras:
        """The words of frames ``[start, stop)`` only (header and parameters as they are: see :meth:`slice`)."""
        s = self.samples
        return replace(self, residual_words=self.residual_words[start:stop].copy(),
                       track_words=self.track_words[start:stop].copy(), fix_mask=self.fix_mask[start:stop].copy(),
                       fix_words=self.fix_words[start:stop].copy(),
                       analog_words=self.analog_words[start * s:stop * s].copy())

    def slice(self, start: int, stop: int | None = None, origin: int = 0) -> C3DExtras:
        """Frames ``start:stop``: the header's frame numbers, POINT:FRAMES and TRIAL:ACTUAL_START_FIELD /
        ACTUAL_END_FIELD patched, the tail dropped (the file is padded to a block when written).

        ``origin``: the frame of the whole clip these extras' first row is (extras holding only some blocks'
        rows, :meth:`rows`; the header and parameters are the whole clip's).
        """
        rng = range(self.frames)[start:stop]
        a, b = rng.start, rng.stop
        if a == 0 and b == self.frames and origin == 0:
            return self
        n = max(b - a, 0)
        order = PROCESSOR_ORDER[self.processor]
        head = bytearray(self.header)
        first = struct.unpack(f"{order}H", head[6:8])[0] + origin + a
        struct.pack_into(f"{order}HH", head, 6, first & 0xFFFF, (first + n - 1) & 0xFFFF)
        params = bytearray(self.params)
        fp = self.frame_params
        if "POINT:FRAMES" in fp:
            self._put(params, fp["POINT:FRAMES"], n)
        start_field = first
        if "TRIAL:ACTUAL_START_FIELD" in fp:
            start_field = self._get(fp["TRIAL:ACTUAL_START_FIELD"]) + origin + a
            self._put(params, fp["TRIAL:ACTUAL_START_FIELD"], start_field)
        if "TRIAL:ACTUAL_END_FIELD" in fp:
            self._put(params, fp["TRIAL:ACTUAL_END_FIELD"], start_field + n - 1)
        return replace(self.rows(a, b), header=bytes(head), params=bytes(params), tail=None)
