"""Subsampling baseline (the pattern-indexing paper's baseline): keep every N-th frame, spline in between.

Encoder: the value matrix (:mod:`.common`: channels with unwrapped angles, or marker coordinates with
gaps filled) is sampled at frames ``0, N, 2N, ...`` and at the last frame; those key frames are stored as
**float32** (no entropy coding, as in the paper). Decoder: a cubic spline (scipy ``CubicSpline``,
not-a-knot ends) through the key frames, evaluated at every frame; markers get their gaps back as NaN.

Options: ``factor`` N (integer >= 1, default 4). ``factor=1`` keeps every frame: exact up to float32.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mocapz.codecs import CodecInfo
from mocapz.codecs.baselines.common import (
    f32_array,
    f32_bytes,
    finish,
    gaps_bytes,
    gaps_from,
    layout_columns,
    read_uvarints,
    uvarints,
    values_of,
)
from mocapz.codecs.correction.wrap import apply_window, corrected
from mocapz.codecs.options import Option
from mocapz.codecs.ratesearch import check_target, coarsest_meeting
from mocapz.codecs.target import TARGET_OPTIONS, Target
from mocapz.errors import FormatError
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion

VERSION = 3  # 2: the correction layer (codecs/correction); 3: its knots and details in two streams
DEFAULT_FACTOR = 4
MAX_SEARCHED_FACTOR = 256
OPTIONS: tuple[Option, ...] = TARGET_OPTIONS + (
    Option("factor", "int", "keep every N-th frame (and the last), cubic spline in between", low=1, high=1_000_000,
           default_text=f"{DEFAULT_FACTOR}; searched with a target"),
)


def key_frames(frames: int, factor: int) -> np.ndarray:
    """Indices of the stored frames: ``0, N, 2N, ...`` and the last frame, ``(keys,)`` int64."""
    if frames <= 0:
        return np.zeros(0, dtype=np.int64)
    keys = np.arange(0, frames, factor, dtype=np.int64)
    if keys[-1] != frames - 1:
        keys = np.append(keys, frames - 1)
    return keys


def interpolate(keys: np.ndarray, values: np.ndarray, frames: int) -> np.ndarray:
    """Cubic-spline interpolation of key values ``(keys, columns)`` at every frame -> ``(frames, columns)``."""
    if len(keys) == 0:
        return np.zeros((frames, values.shape[1]))
    if len(keys) == 1:
        return np.repeat(values[:1], frames, axis=0)
    from scipy.interpolate import CubicSpline  # noqa: I001 (on use: scipy loads slowly)
    spline = CubicSpline(keys.astype(np.float64), values, axis=0, bc_type="not-a-knot")
    out = spline(np.arange(frames, dtype=np.float64))
    out[keys] = values  # exact at the knots
    return out


def encode(motion: AnyMotion, **options: Any) -> dict[str, bytes]:
    """Sections: ``head`` (factor), ``keys`` (float32 key-frame values), ``gaps`` (markers with gaps)."""
    target = Target.from_options(options, motion.unit_cm)
    if not target.active:
        return encode_factor(motion, options.get("factor") or DEFAULT_FACTOR)
    if options.get("factor") is not None:
        return check_target(motion, target, encode_factor(motion, options["factor"]), decode, "subsample")
    factors = range(1, max(1, min(motion.n_frames, MAX_SEARCHED_FACTOR)) + 1)
    return coarsest_meeting(motion, target, factors, lambda f: encode_factor(motion, f), decode, "subsample")


def encode_factor(motion: AnyMotion, factor: int) -> dict[str, bytes]:
    """Sections keeping every ``factor``-th frame."""
    v = values_of(motion)
    keys = key_frames(len(v.x), factor)
    sections = {"head": uvarints(factor), "keys": f32_bytes(v.x[keys])}
    if v.gaps is not None:
        sections["gaps"] = gaps_bytes(v.gaps)
    return sections


def decode(sections: dict[str, bytes], header: ClipHeader) -> AnyMotion:
    """Inverse of :func:`encode` (lossy: spline between key frames)."""
    frames = header.frames
    cols, _, _ = layout_columns(header)
    try:
        (factor,), _ = read_uvarints(sections["head"], 1)
        if factor < 1:
            raise FormatError(None, "corrupted subsample stream (factor 0)")
        keys = key_frames(frames, factor)
        values = f32_array(sections["keys"], (len(keys), cols))
    except KeyError as exc:
        raise FormatError(None, f"corrupted subsample stream (missing section {exc})") from None
    x = interpolate(keys, values, frames)
    return finish(header, x, gaps_from(sections, header), round_decimals=True)


ENCODE, DECODE = corrected(encode, decode, "subsample", OPTIONS)
INFO = CodecInfo(name="subsample", version=VERSION, kinds=("skeleton", "markers"), encode=ENCODE,
                 decode=DECODE, options=OPTIONS, decode_window=apply_window,

                 summary="baseline: every N-th frame kept, cubic spline in between (the pattern paper's Fig. 9)")
