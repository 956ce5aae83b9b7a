"""Segment-based PCA baseline after Liu & McMillan 2006 ("Segment-based human motion compression", SCA),
the PGA paper's Table 3 baseline.

Encoder: the value matrix (:mod:`.common`, scaled to length units as in :mod:`.pca`) is cut greedily
into segments whose poses lie near a low-dimensional linear space: a segment grows by steps of
``frame_rate / 8`` frames while at most ``components`` principal components keep ``variance`` of its
variance (and up to ``max_segment`` frames). Each segment gets its own PCA (the fewest components
keeping ``variance``, at most ``components``); only the coefficients of key frames (every ``key``-th
frame of the segment and its last frame) are stored, the others are interpolated by a cubic spline (the
paper's key-frame projections with spline in-betweens). Stored as **float32**, no entropy coding: per
segment its mean ``(columns,)``, directions ``(K, columns)`` and key coefficients ``(keys, K)``; segment
lengths and ``K`` as varints.

Options: ``variance`` (0 < v <= 1, default 0.99), ``components`` (1..columns, default 6), ``key``
(key-frame spacing >= 1, default 4), ``max_segment`` (frames, default 4 s of motion).
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
from mocapz.codecs.baselines.pca import column_scale, components_for, fit, scale_of
from mocapz.codecs.baselines.subsample import interpolate, key_frames
from mocapz.codecs.correction.wrap import apply_window, corrected
from mocapz.codecs.options import Option
from mocapz.codecs.ratesearch import check_target, coarsest_meeting
from mocapz.codecs.target import TARGET_OPTIONS, Target
from mocapz.errors import FormatError, OptionError
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion

VERSION = 3  # 2: the correction layer (codecs/correction); 3: its knots and details in two streams
OPTIONS: tuple[Option, ...] = TARGET_OPTIONS + (
    Option("variance", "float", "fraction of each segment's variance kept", low=0.0, high=1.0, low_open=True,
           default=0.99),
    Option("components", "int", "most principal components per segment", low=1, high=1_000_000,
           default_text="6; searched with a target"),
    Option("key", "int", "key-frame spacing inside a segment; cubic spline in between", low=1, high=1_000_000,
           default=4),
    Option("max_segment", "int", "longest segment in frames", low=2, high=10_000_000, default_text="4 s of frames"),
)
DEFAULT_COMPONENTS = 6


def needed_components(y: np.ndarray, variance: float) -> int:
    """Fewest principal components of ``y`` ``(frames, columns)`` keeping ``variance`` of its variance."""
    if len(y) < 2:
        return 1
    s = np.linalg.svd(y - y.mean(axis=0), compute_uv=False)
    return components_for(s, variance)


def segment(y: np.ndarray, variance: float, components: int, step: int, max_segment: int) -> list[int]:
    """Greedy segmentation of ``y`` ``(frames, columns)``: the segment lengths (sum = frames)."""
    frames = len(y)
    lengths: list[int] = []
    s = 0
    while s < frames:
        e = min(s + 2 * step, frames)
        while e < frames and e - s < max_segment:
            e2 = min(e + step, frames, s + max_segment)
            if needed_components(y[s:e2], variance) > components:
                break
            e = e2
        if frames - e < step:  # no sliver at the end
            e = frames
        lengths.append(e - s)
        s = e
    return lengths


def encode(motion: AnyMotion, **options: Any) -> dict[str, bytes]:
    """Sections: ``head`` (key spacing, segment count), ``segs`` (length, K per segment), ``data``
    (float32 blocks), ``gaps`` (markers with gaps)."""
    target = Target.from_options(options, motion.unit_cm)
    cols = max(1, motion.values[:1].size)
    components = options.get("components")
    if components is not None and components > cols:
        raise OptionError(f"option components (--components) of the segpca codec must be at most {cols} for "
                          f"this clip (its columns); got {components}")
    if not target.active:
        return encode_with(motion, options, options["variance"], components or DEFAULT_COMPONENTS)
    if components is not None:
        sections = encode_with(motion, options, options["variance"], components)
        return check_target(motion, target, sections, decode, "segpca")
    return coarsest_meeting(motion, target, range(cols, 0, -1), lambda c: encode_with(motion, options, 1.0, c),
                            decode, "segpca")


def encode_with(motion: AnyMotion, options: dict[str, Any], variance: float, components: int) -> dict[str, bytes]:
    """Sections for a variance share and a most-components count (``key``, ``max_segment`` from options)."""
    v = values_of(motion)
    key = options["key"]
    rate = float(motion.frame_rate) if motion.frame_rate > 0 else 120.0
    max_segment = options.get("max_segment") or max(8, round(4 * rate))
    step = max(4, round(rate / 8))
    y = v.x * scale_of(motion)
    lengths = segment(y, variance, components, step, max_segment)
    head, blocks, start = [], [], 0
    for n in lengths:
        mean, basis, coef = fit(y[start : start + n], variance, None)
        if basis.shape[0] > components:
            mean, basis, coef = fit(y[start : start + n], variance, components)
        keys = key_frames(n, key)
        head += [n, basis.shape[0]]
        blocks += [f32_bytes(mean), f32_bytes(basis), f32_bytes(coef[keys])]
        start += n
    sections = {"head": uvarints(key, len(lengths)), "segs": uvarints(*head), "data": b"".join(blocks)}
    if v.gaps is not None:
        sections["gaps"] = gaps_bytes(v.gaps)
    return sections


def decode(sections: dict[str, bytes], header: ClipHeader) -> AnyMotion:
    """Inverse of :func:`encode`: per segment, splined key coefficients times its basis plus its mean."""
    frames = header.frames
    cols, _, _ = layout_columns(header)
    try:
        (key, count), _ = read_uvarints(sections["head"], 2)
        head, _ = read_uvarints(sections["segs"], 2 * count)
        data = sections["data"]
    except KeyError as exc:
        raise FormatError(None, f"corrupted segpca stream (missing section {exc})") from None
    if key < 1 or sum(head[0::2]) != frames:
        raise FormatError(None, "corrupted segpca stream (segment lengths)")
    y = np.zeros((frames, cols))
    pos = start = 0
    for n, k in zip(head[0::2], head[1::2], strict=True):
        keys = key_frames(n, key)
        sizes = (cols, k * cols, len(keys) * k)
        parts = []
        for size in sizes:
            parts.append(data[pos : pos + 4 * size])
            pos += 4 * size
        mean = f32_array(parts[0], (cols,))
        basis = f32_array(parts[1], (k, cols))
        coef = interpolate(keys, f32_array(parts[2], (len(keys), k)), n)
        y[start : start + n] = coef @ basis + mean
        start += n
    if pos != len(data):
        raise FormatError(None, "corrupted segpca stream (data size)")
    return finish(header, y / column_scale(header), gaps_from(sections, header), round_decimals=True)


ENCODE, DECODE = corrected(encode, decode, "segpca", OPTIONS)
INFO = CodecInfo(name="segpca", version=VERSION, kinds=("skeleton", "markers"), encode=ENCODE, decode=DECODE,
                 options=OPTIONS, decode_window=apply_window,
                 summary="baseline: PCA per segment, key-frame coefficients (Liu & McMillan 2006)")
