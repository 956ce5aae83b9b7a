"""A named precision for the parts of a C3D file that are not marker positions: the analog channels and the
model-output tracks (Plug-in-Gait angles, forces, moments, powers). Both are kept bit for bit unless the user
names a precision; then each value comes back within it.

A precision is the largest error of any one value, in the value's own unit: an analog channel's unit
(ANALOG:UNITS: the stored number times ``|ANALOG:SCALE * ANALOG:GEN_SCALE|``, the offset cancels), a track's
unit (``deg``, ``N``, ``Nmm``, ``W``...; x, y and z each). It is given as one number for every channel or
track, or per name: ``"Fz1=0.5"`` (an analog label), ``"angles=0.01"`` (a track kind: angles, forces,
moments, powers, reactions, scalars) or ``"LKneeAngles=0.01"`` (a track label); a name given wins over its
kind, a kind over the plain number.

The stored words are rounded to a step per column (:func:`quantise_columns`): int16 words to a multiple of
an odd step ``q = 2 floor(p / u) + 1`` (``u`` the unit of one stored number, so the error is at most
``floor(p / u)`` numbers), float32 words to ``k s`` with ``s`` just under ``2 p / u``, every column checked
after rounding (a column that would miss its precision, or holds non-finite words, stays exact; float
words that hold whole numbers, such as converter counts, are rounded to odd whole steps as int16 words are). Then
:func:`encode_stepped` codes the step table, the quotients ``k`` of the rounded columns and the exact
columns (through :func:`mocapz.format.extras_words.encode_words`).

Stepped word matrix (the mode byte :data:`STEPPED`, which no plain word matrix uses)::

    byte 0x40, uvarint n (rounded columns), n x (uvarint column, float64 LE step), uvarint length L +
    L bytes: the (rows, n) quotients (1 byte prediction order 0-2 + an integer matrix,
    mocapz.format.entropy), then the plain word matrix of the other columns
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from mocapz.errors import FormatError, OptionError
from mocapz.format.entropy import decode_int_matrix, encode_int_matrix, read_uvarint, write_uvarint
from mocapz.model.c3d_extras import C3DExtras, float_values, float_words

STEPPED = 0x40
TRACK_KINDS = ("ANGLES", "FORCES", "MOMENTS", "POWERS", "REACTIONS", "SCALARS")
_SHRINK = 1.0 - 2.0**-20  # float steps just under 2p: float32 rounding of k s stays inside p
MAX_QUOTIENT = 1 << 22  # |k| below it: k s rounded to float32 and divided by s gives k back


def _bad(what: str) -> FormatError:
    return FormatError(None, f"corrupted C3D extras ({what})")


# ----------------------------------------------------------------------------------------- options
def _number(text: Any, what: str) -> float:
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise OptionError(f"{what}: expected a number (the largest error, in the value's own unit), "
                          f"got {text!r}") from None
    if not np.isfinite(value) or value <= 0:
        raise OptionError(f"{what}: expected a positive number, got {text!r}")
    return value


def parse_precision(spec: str | float | Mapping[str, Any] | Sequence[Any] | None, what: str) -> dict[str, float]:
    """``{name: precision}`` of a ``--analog-precision`` / ``--track-precision`` value (``""``: every one).

    ``spec``: a number, ``"NAME=NUMBER"``, a comma-separated or repeated list of those, or a mapping.
    """
    if spec is None:
        return {}
    if isinstance(spec, Mapping):
        items = [(str(k).strip(), v) for k, v in spec.items()]
    else:
        parts = [spec] if isinstance(spec, str | int | float) else list(spec)
        items = []
        for part in parts:
            for item in str(part).split(","):
                name, sep, value = item.rpartition("=")
                if not item.strip():
                    continue
                items.append((name.strip() if sep else "", value.strip()))
    out: dict[str, float] = {}
    for name, value in items:
        if isinstance(value, bool):
            raise OptionError(f"{what}: expected a number, got {value!r}")
        if name in out:
            raise OptionError(f"{what}: {name or 'the plain number'} given twice")
        out[name] = _number(value, f"{what} {name}".strip())
    return out


@dataclass(frozen=True)
class ExtrasPrecision:
    """The precisions asked for (:func:`parse_precision` tables); empty tables keep everything exact."""

    analog: dict[str, float]
    tracks: dict[str, float]

    @classmethod
    def of(cls, analog: Any = None, tracks: Any = None) -> ExtrasPrecision | None:
        """Checked precisions, or None when neither is given (everything exact)."""
        a, t = parse_precision(analog, "--analog-precision"), parse_precision(tracks, "--track-precision")
        return cls(a, t) if a or t else None

    def per_channel(self, labels: Sequence[str]) -> np.ndarray:
        """``(channels,)`` the precision of each analog channel, 0 where exact."""
        self._known(self.analog, set(labels), "--analog-precision", "analog channel")
        return np.array([self.analog.get(s, self.analog.get("", 0.0)) for s in labels], dtype=np.float64)

    def per_track(self, labels: Sequence[str], kinds: Sequence[str]) -> np.ndarray:
        """``(tracks,)`` the precision of each track (by label, else kind, else the plain number), 0: exact."""
        table = {k.upper() if k.upper() in TRACK_KINDS else k: v for k, v in self.tracks.items()}
        self._known(table, set(labels) | set(TRACK_KINDS), "--track-precision", "track or kind")
        return np.array([table.get(s, table.get(k, table.get("", 0.0))) for s, k in zip(labels, kinds, strict=True)],
                        dtype=np.float64)

    @staticmethod
    def _known(table: dict[str, float], names: set[str], what: str, noun: str) -> None:
        unknown = sorted(k for k in table if k and k not in names)
        if unknown:
            raise OptionError(f"{what}: no {noun} named {', '.join(unknown)} in this file")


# ----------------------------------------------------------------------------------------- rounding
def quantise_columns(words: np.ndarray, is_float: bool, processor: int, unit: np.ndarray,
                     precision: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Round the columns of a ``(rows, cols)`` word matrix to their precision.

    Args:
        words: int64 words (int16 values, or float32 bits as :func:`~mocapz.model.c3d_extras.word_dtype`).
        unit: ``(cols,)`` the unit of one stored number; precision: ``(cols,)`` the largest error, 0: exact.

    Returns:
        the rounded words and ``(cols,)`` float64 steps in stored numbers (0 where a column stays exact).
    """
    out = np.array(words, dtype=np.int64)
    steps = np.zeros(out.shape[1])
    for c in np.flatnonzero((precision > 0) & (unit > 0) & np.isfinite(unit)):
        room = precision[c] / unit[c]  # the largest error in stored numbers
        w = out[:, c]
        if is_float:
            v = float_values(w, processor)
            step = 2.0 * room * _SHRINK
            if not np.isfinite(v).all() or not np.isfinite(step) or step <= 0:
                continue
            if np.array_equal(v, np.round(v)) and np.abs(v).max(initial=0) < 1 << 22:  # counts stored as floats
                step = 2 * np.floor(min(room, 1 << 16)) + 1
                if step < 3:
                    continue
            k = np.round(v / step) + 0.0  # -0.0 to 0.0: the quotient is an integer
            if np.abs(k).max(initial=0) >= MAX_QUOTIENT:
                continue
            new = float_words(k * step, processor)
            err = np.abs(float_values(new, processor) - v)
        else:
            q = 2 * np.floor(min(room, 1 << 16)) + 1
            if q < 3:
                continue
            k = np.clip(np.round(w / q), np.ceil(-32768 / q), np.floor(32767 / q))
            new = (k * q).astype(np.int64)
            err = np.abs(new - w).astype(np.float64)
            step = q
        if (err <= room).all():
            out[:, c], steps[c] = new, step
    return out, steps


def quantised_extras(extras: C3DExtras, precision: ExtrasPrecision) -> tuple[C3DExtras, np.ndarray, np.ndarray]:
    """The extras with analog and track words rounded to ``precision``; and the steps of the analog columns
    ``(channels,)`` and of the track columns ``(tracks * 3,)`` (0: exact)."""
    fmt = (extras.is_float, extras.processor)
    f, t = extras.frames, extras.track_index.size
    ana_steps = np.zeros(extras.channels)
    analog = extras.analog_words
    if precision.analog and extras.channels:
        if extras.analog_scales is None or extras.analog_labels is None:
            raise OptionError("--analog-precision: this motion carries no ANALOG:SCALE (a motion decoded from "
                              "a .mcz): write it to a .c3d file and compress that")
        p = precision.per_channel(extras.analog_labels)
        analog, ana_steps = quantise_columns(analog, *fmt, extras.analog_scales, p)
    trk_steps = np.zeros(3 * t)
    track = extras.track_words
    if precision.tracks and t:
        p = np.repeat(precision.per_track(extras.track_labels, extras.track_kinds), 3)
        unit = np.ones(3 * t) if extras.is_float else np.repeat(extras.scales[extras.track_index], 3)
        flat, trk_steps = quantise_columns(track.reshape(f, 3 * t), *fmt, unit, p)
        track = flat.reshape(f, t, 3)
    return replace(extras, analog_words=analog, track_words=track), ana_steps, trk_steps


# ----------------------------------------------------------------------------------------- coding
def _ints(values: np.ndarray) -> bytes:
    """An integer matrix by the best of prediction orders 0-2 (differences down the columns)."""
    options = []
    for order in (0, 1, 2):
        res = np.diff(values, n=order, axis=0, prepend=np.zeros((order, values.shape[1]), dtype=np.int64))
        options.append(bytes([order]) + encode_int_matrix(res))
    return min(options, key=len)


def encode_stepped(words: np.ndarray, steps: np.ndarray, is_float: bool, processor: int,
                   plain: Callable[[np.ndarray], bytes]) -> bytes:
    """A word matrix whose columns with a step > 0 are rounded (:func:`quantise_columns`); ``plain`` codes the
    exact columns (:func:`mocapz.format.extras_words.encode_words` with the storage bound)."""
    cols = np.flatnonzero(steps > 0)
    w = np.asarray(words, dtype=np.int64)
    if is_float:
        k = np.round(float_values(w[:, cols], processor) / steps[cols]).astype(np.int64)
        exact = np.array_equal(float_words(k * steps[cols], processor), w[:, cols])
    else:
        k = w[:, cols] // steps[cols].astype(np.int64)
        exact = np.array_equal(k * steps[cols].astype(np.int64), w[:, cols])
    if not exact:
        raise ValueError("encode_stepped: the words are not the rounded words of their steps")
    table = b"".join(write_uvarint(int(c)) + struct.pack("<d", float(steps[c])) for c in cols)
    body = _ints(k)
    rest = np.delete(w, cols, axis=1)
    return bytes([STEPPED]) + write_uvarint(cols.size) + table + write_uvarint(len(body)) + body + plain(rest)


def decode_stepped(data: bytes, shape: tuple[int, int], is_float: bool, processor: int,
                   plain: Callable[[bytes, tuple[int, int]], np.ndarray]) -> np.ndarray:
    """Inverse of :func:`encode_stepped` for the ``(rows, cols)`` the header declares."""
    rows, cols = shape
    n, pos = read_uvarint(data, 1)
    if n > cols or pos + 9 * n > len(data):
        raise _bad("step table")
    index, steps = np.zeros(n, dtype=np.int64), np.zeros(n)
    for i in range(n):
        index[i], pos = read_uvarint(data, pos)
        if pos + 8 > len(data):  # an index's uvarint may take more than the one byte counted above
            raise _bad("step table")
        (steps[i],) = struct.unpack_from("<d", data, pos)
        pos += 8
    if pos > len(data) or index.size != np.unique(index).size or (index >= cols).any() or not (
            np.isfinite(steps).all() and (steps > 0).all()):
        raise _bad("step table")
    if not is_float and ((steps != np.round(steps)) | (steps > 1 << 17)).any():
        raise _bad("integer step")
    size, pos = read_uvarint(data, pos)
    if pos + size > len(data) or size < 1 or data[pos] > 2:
        raise _bad("stepped columns")
    k = decode_int_matrix(bytes(data[pos + 1:pos + size]), (rows, n))
    for _ in range(data[pos]):
        k = np.cumsum(k, axis=0)
    out = np.zeros(shape, dtype=np.int64)
    keep = np.setdiff1d(np.arange(cols), index)
    out[:, keep] = plain(bytes(data[pos + size:]), (rows, keep.size))
    if n == 0:
        return out
    if np.abs(k).max() >= MAX_QUOTIENT:
        raise _bad("stepped value out of range")
    if is_float:
        out[:, index] = float_words(k * steps, processor)
    else:
        ints = k * steps.astype(np.int64)
        if ints.min() < -32768 or ints.max() > 32767:
            raise _bad("int16 word out of range")
        out[:, index] = ints
    return out
