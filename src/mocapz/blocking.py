"""A clip coded as independent blocks of frames, so that a frame range decodes only the blocks it needs.

Every block is a clip of its own for the codec (its own rate control, lifting and entropy state); a target
met on every block is met on the clip: the max error is per point and frame, the distortion ``d`` and the
ARMS are means whose per-block bounds add up (a block's deviation from its own mean is at most its deviation
from the clip's). The byte layout is in :mod:`mocapz.format.blocks`.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any

import numpy as np

from mocapz.errors import OptionError
from mocapz.format import blocks
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, BlockOf, Motion

Sections = dict[str, bytes]

MIN_DEFAULT_FRAMES = 128  # a block's own tables (predictors, scales) cost a few % below this
BEFORE_FRAMES = 65  # decoded frames of the block before that a continued block is given: the last, its first knot,
# and 2 ** 6 before it (the lossy codecs' deepest lifting predicts across the edge from them, codecs.correction)

_SPEC = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(s|f|frames?|seconds?)?\s*$", re.IGNORECASE)


def block_frames(spec: int | float | str | None, frame_rate: float, default_seconds: float) -> int:
    """Frames per block for a ``--block`` value: frames (``240``, ``240f``), seconds (``4s``), ``0`` for the
    whole clip in one block, None for the codec's default (``default_seconds``, at least
    :data:`MIN_DEFAULT_FRAMES` frames; 0: one block)."""
    if spec is None:  # the codec's default, never under MIN_DEFAULT_FRAMES (a 30-fps clip's 1 s is too short)
        return max(MIN_DEFAULT_FRAMES, round(default_seconds * frame_rate)) if default_seconds > 0 else 0
    if isinstance(spec, bool):
        raise OptionError(f"--block: expected frames (240), seconds (4s) or 0, got {spec!r}")
    if isinstance(spec, int | float):
        text = str(spec)
    else:
        text = spec
    m = _SPEC.match(text)
    if not m:
        raise OptionError(f"--block: expected frames (240), seconds (4s) or 0 (one block), got {spec!r}")
    value, unit = float(m.group(1)), (m.group(2) or "f").lower()
    if unit.startswith("s"):
        return max(1, round(value * frame_rate)) if value > 0 else 0
    if value != int(value):
        raise OptionError(f"--block: a number of frames must be whole, got {spec!r}")
    return int(value)


def encode(encode_one: Callable[..., Sections], motion: AnyMotion, options: dict[str, Any], frames_per_block: int,
           progress: Callable[[int], None] | None = None) -> Sections:
    """The codec's sections for ``motion``: as one clip when it fits in a block (``frames_per_block`` 0 or more
    than half the clip), else every block's sections and the index (:func:`mocapz.format.blocks.pack`).
    ``progress(frames)`` is called after each block."""
    n = motion.n_frames
    if frames_per_block <= 0 or n < 2 * frames_per_block:
        out = encode_one(motion, **options)
        if progress:
            progress(n)
        return out
    index = blocks.BlockIndex(n, frames_per_block)
    parts = []
    cache: dict[str, Any] = {}  # what encoders compute once on the whole clip (BlockOf.cache)
    for i in range(index.count):
        a, b = index.bounds(i)
        piece = motion.slice(a, b)
        piece = replace(piece, metadata={**piece.metadata, "block_of": BlockOf(motion, a, b, cache)})
        parts.append(encode_one(piece, **options))
        if progress:
            progress(b - a)
    return blocks.pack(index, parts)


def decode_spans(decode_one: Callable[[Sections, ClipHeader], AnyMotion], parts: list[Sections],
                 spans: list[tuple[int, int]], header: ClipHeader, start: int, stop: int) -> AnyMotion:
    """Frames ``[start, stop)`` from blocks ``parts`` covering frames ``spans`` ``[(a, b), ...]`` (in order,
    end to end), decoding only the blocks the range meets (:func:`iter_spans`)."""
    return joined(list(iter_spans(decode_one, parts, spans, header, start, stop)))


def iter_spans(decode_one: Callable[[Sections, ClipHeader], AnyMotion], parts: list[Sections],
               spans: list[tuple[int, int]], header: ClipHeader, start: int, stop: int) -> Iterator[AnyMotion]:
    """The pieces of frames ``[start, stop)`` block by block, as :func:`decode_spans` joins them: the blocks the
    range meets, decoded from the last block before them that decodes on its own (a stream's blocks may
    continue the block before them, :data:`~mocapz.format.blocks.CONTINUES`)."""
    meets = [i for i, (a, b) in enumerate(spans) if a < stop and b > start]
    first = meets[0]
    while first > 0 and blocks.CONTINUES in parts[first]:
        first -= 1
    before = None
    batch = spans[meets[-1]][1] - spans[first][0]  # the frames of every block decoded here
    for i in range(first, meets[-1] + 1):
        a, b = spans[i]
        try:
            piece = decode_block(decode_one, parts[i], header, b - a, before, batch)
        except ValueError as exc:
            raise ValueError(f"block {i}: {exc}") from None
        before = last_frames(piece)
        if i >= meets[0]:
            yield piece.slice(max(start - a, 0), min(stop, b) - a)


def decode_block(decode_one: Callable[[Sections, ClipHeader], AnyMotion], part: Sections, header: ClipHeader,
                 frames: int, before: np.ndarray | None, batch: int | None = None) -> AnyMotion:
    """One block's motion (ValueError if it is not ``frames`` frames long); a block that continues the one before
    it (its section :data:`~mocapz.format.blocks.CONTINUES`) is given that block's last decoded frames
    ``before`` (:func:`last_frames`; ValueError without it); ``batch``: the frames of all the blocks decoded with
    it (:attr:`~mocapz.model.header.ClipHeader.batch_frames`)."""
    if blocks.CONTINUES in part:
        if before is None:
            raise ValueError("it continues the block before it, which is missing")
        part = {k: v for k, v in part.items() if k != blocks.CONTINUES}
    else:
        before = None
    piece = decode_one(part, replace(header, frames=frames, before=before, batch_frames=batch))
    if piece.n_frames != frames:
        raise ValueError(f"it decoded to {piece.n_frames} frames, not {frames}")
    return piece


def last_frames(motion: AnyMotion) -> np.ndarray:
    """``(frames, columns)`` the values of a motion's last :data:`BEFORE_FRAMES` frames (or all, if fewer;
    flattened per frame; float64), what the block after it continues from."""
    v = np.asarray(motion.values[-BEFORE_FRAMES:], dtype=np.float64)
    return v.reshape(v.shape[0], -1)


def joined(pieces: list[AnyMotion]) -> AnyMotion:
    """The pieces one after the other, as one motion (the first one's attributes; a marker quantum kept only
    if every piece has it)."""
    first = pieces[0]
    if len(pieces) == 1:
        return first
    values = np.concatenate([p.values for p in pieces])
    if isinstance(first, Motion):
        return replace(first, channels=values)
    quantum = first.quantum if all(p.quantum == first.quantum for p in pieces) else None
    return replace(first, positions=values, quantum=quantum)


def frame_range(frames: slice | range | tuple[int, int] | None, n: int) -> tuple[int, int]:
    """``(start, stop)`` of a frame selection in a clip of ``n`` frames (None: all; negative ends count
    from the end, as in Python). OptionError when it selects nothing."""
    if frames is None:
        return 0, n
    if isinstance(frames, tuple):
        frames = slice(*frames)
    if isinstance(frames, range):
        if frames.step != 1:
            raise OptionError("frames: a range with step 1")
        frames = slice(frames.start, frames.stop)
    if not isinstance(frames, slice) or frames.step not in (None, 1):
        raise OptionError(f"frames: expected a slice of consecutive frames, got {frames!r}")
    a, b, _ = frames.indices(n)
    if b <= a:
        raise OptionError(f"frames {frames.start}:{frames.stop} select no frame of this clip ({n} frames)")
    return a, b
