"""The whole clip behind a block (:class:`~mocapz.model.motion.BlockOf`): a block is corrected as the whole clip
would be, so that coding a clip in blocks costs little.

Three decisions depend on more than the block's own frames: the foot contacts (a foot is planted within 5 cm of
its lowest height over the seconds before: a block's first frames look back into the block before it), the body
height (bounds when the length unit is unknown) and the added acceleration energy allowed (a fraction of the
original's: a calm block alone would get almost none). Each is computed once on the whole clip (memoised in
``BlockOf.cache``) and cut to the block. The jitter budget is spent block after block: a block may add what
the clip's allowance for the frames up to its end leaves after the blocks before it (what a block leaves
unused passes on), so the clip's added jitter stays within the allowed fraction of its energy; a block's energy
takes in the accelerations across its first edge, from the last frames of the block before as coded
(:func:`edge`), as the file's jitter does; a block on a model base (which starts afresh at its edge) takes the
feet's windows across its first edge into its check likewise (:func:`feet_before`), as the file's foot skate does.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from mocapz.codecs.correction.bounds import Layout, covers
from mocapz.codecs.target import ErrorMetric
from mocapz.metrics.chunks import frame_chunks
from mocapz.metrics.contacts import Contacts, find_contacts
from mocapz.model.motion import AnyMotion, BlockOf, MarkerMotion

EDGE = 2  # frames before a block that the accelerations of its first frames take in (second differences)
Edge = tuple[np.ndarray, np.ndarray, np.ndarray]  # decoded and original positions, present samples (:func:`tail`)


def block_of(motion: AnyMotion) -> BlockOf | None:
    """The clip ``motion`` is a block of, if any."""
    ctx = motion.metadata.get("block_of")
    return ctx if isinstance(ctx, BlockOf) else None


def _whole(ctx: BlockOf) -> tuple[np.ndarray, np.ndarray]:
    """The whole clip's positions ``(frames, points, 3)`` and present samples ``(frames, points)``."""
    if "positions" not in ctx.cache:
        metric = ErrorMetric(ctx.clip)
        valid = np.ones(metric.positions.shape[:2], dtype=bool) if metric.valid is None else metric.valid
        ctx.cache["positions"] = (metric.positions, valid)
    out: tuple[np.ndarray, np.ndarray] = ctx.cache["positions"]
    return out


def contacts(ctx: BlockOf) -> Contacts:
    """The whole clip's contacts, cut to the block's frames."""
    whole = contacts_of_clip(ctx)
    return Contacts(whole.up, whole.feet, whole.steps[ctx.start:max(ctx.stop - 1, ctx.start)])


def contacts_of_clip(ctx: BlockOf) -> Contacts:
    """The whole clip's contacts (computed once)."""
    if "contacts" not in ctx.cache:
        pos, valid = _whole(ctx)
        with warnings.catch_warnings():  # markers missing in every frame
            warnings.simplefilter("ignore", RuntimeWarning)
            # a stream of markers holds the two lowest pairs: the whole file's feet (its lowest two on average,
            # which the metric measures) may be the heels or the toes of the frames seen so far
            pairs = 2 if "stream" in ctx.cache and isinstance(ctx.clip, MarkerMotion) else 1
            ctx.cache["contacts"] = find_contacts(ctx.clip, pos, valid, ctx.clip.unit_cm, pairs)
    whole: Contacts = ctx.cache["contacts"]
    return whole


def cached(ctx: BlockOf, key: str, make: Any) -> Any:
    """``make(positions, valid)`` on the whole clip, computed once."""
    if key not in ctx.cache:
        ctx.cache[key] = make(*_whole(ctx))
    return ctx.cache[key]


def squared_accelerations(a: np.ndarray) -> np.ndarray:
    """``(frames - 2, points)`` squared second differences ``|a[t+2] - a[t+1] - (a[t+1] - a[t])|^2`` of positions
    ``a`` ``(frames, points, 3)`` (NaN as 0), :data:`~mocapz.metrics.figures.CHUNK_FRAMES` frames at a time (the
    same numbers, without a whole clip's temporaries)."""
    out = np.empty((max(a.shape[0] - 2, 0), a.shape[1]))
    for part in frame_chunks(out.shape[0]):
        out[part] = (np.diff(np.nan_to_num(a[part.start:part.stop + 2]), 2, axis=0) ** 2).sum(axis=2)
    return out


def acceleration_energy(a: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(frames - 2, points)`` squared second differences of positions ``a`` ``(frames, points, 3)`` (0 where a
    sample is missing) and where all three samples are present."""
    ok = valid[2:] & valid[1:-1] & valid[:-2]
    return np.where(ok, squared_accelerations(a), 0.0), ok


def energy_reference(ctx: BlockOf | None, own: float, fraction: float) -> float:
    """What the block's added acceleration energy must stay under ``fraction`` of: its own energy ``own``
    alone, or within a clip the clip's energy up to the block's end (its share by frames) less what the
    blocks before it added (over ``fraction``)."""
    if ctx is None:
        return own
    total, n = cached(ctx, "energy", lambda a, v: (float(acceleration_energy(a, v)[0].sum()), a.shape[0]))
    left = total * ctx.stop / max(n, 1) - ctx.cache.get("jitter_spent", 0.0) / fraction
    return max(left, 1e-9 * total)


def spend(ctx: BlockOf | None, added: float, skated: dict | None = None, tail: Edge | None = None) -> None:
    """Record the acceleration energy the block's chosen correction added (less where it smoothed: the clip's
    allowance is on the sum, as METRICS.md's jitter on the whole file), the feet's added speed so far
    (``skated``, :func:`.feet.speed_sums`) and its last frames (``tail``, :func:`tail`: the next block's
    :func:`edge`); blocks are encoded in order."""
    if ctx is not None:
        ctx.cache["jitter_spent"] = ctx.cache.get("jitter_spent", 0.0) + added
        if skated is not None:
            ctx.cache["skate_spent"] = skated
        if tail is not None:
            ctx.cache["edge"] = tail


def edge(ctx: BlockOf | None) -> Edge | None:
    """The last :data:`EDGE` frames before a block as the blocks before it were coded (none for the first block
    or a clip of its own): the accelerations at the block's first frames reach back to them, and the file's
    jitter counts those as it counts any other (a block that left them out would add jitter at every edge)."""
    kept = before_block(ctx)
    return None if kept is None else (kept[0][-EDGE:], kept[1][-EDGE:], kept[2][-EDGE:])


def before_block(ctx: BlockOf | None) -> Edge | None:
    """Every frame kept from before a block (:func:`tail`: :data:`EDGE` or more), or None."""
    return None if ctx is None else ctx.cache.get("edge")


def tail(before: Edge | None, decoded: np.ndarray, original: np.ndarray, valid: np.ndarray, keep: int = EDGE
         ) -> Edge:
    """The last ``keep`` (at least :data:`EDGE`) frames of the clip so far (the frames ``before`` the block, then
    the block's own): positions ``decoded`` and ``original`` ``(frames, points, 3)`` and present samples ``valid``
    ``(frames, points)``; what the next block's :func:`edge` and :func:`feet_before` give."""
    keep = max(keep, EDGE)
    if before is not None:
        decoded, original, valid = (np.concatenate([b, x]) for b, x in zip(before, (decoded, original, valid),
                                                                           strict=True))
    return (np.array(decoded[-keep:]), np.array(original[-keep:]), np.array(valid[-keep:]))


def feet_before(ctx: BlockOf | None, frames: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Up to ``frames`` frames before a block, as the blocks before it were decoded, for the feet's windows that
    end in the block: decoded and original positions ``(n, points, 3)`` and the whole clip's planted steps from
    the first of them into the block's first frame ``(n, feet)``; None for a clip of its own or a first block."""
    kept = before_block(ctx)
    if ctx is None or kept is None:
        return None
    n = min(frames, len(kept[0]), ctx.start)
    if n <= 0:
        return None
    steps = contacts_of_clip(ctx).steps[ctx.start - n:ctx.start]
    return kept[0][-n:], kept[1][-n:], steps


def carried_skate(ctx: BlockOf | None) -> dict | None:
    """The feet's added speed summed over the blocks before this one (:func:`.feet.speed_sums`), or None."""
    return None if ctx is None else ctx.cache.get("skate_spent", {})


def continued(ctx: BlockOf | None) -> np.ndarray | None:
    """A stream's block after the one before it: the decoded values ``(frames, columns)`` of the frames before the
    block (:class:`mocapz.StreamEncoder` sets ``cache["before"]``), else None."""
    return None if ctx is None else ctx.cache.get("before")


GHOST_LEVELS = 6  # lifting levels whose first detail a continued block predicts across its edge (fit's most)


def followed(ctx: BlockOf | None) -> bool:
    """Whether the stream's next block continues this one (:class:`mocapz.StreamEncoder` sets
    ``cache["followed"]``): its last frame is that block's first knot."""
    return ctx is not None and bool(ctx.cache.get("followed"))


def prefix(before: np.ndarray, rot: np.ndarray, period: float, ghosts: bool = False) -> np.ndarray:
    """The first knot ``(columns,)`` of a continued block coded on a zero base (the correction alone): the decoded
    values of the frame before it (rotations wrapped into their turn, as the block's values are; NaN where a value
    is missing or not finite). The encoder and the decoder compute it alike from the decoded frames ``before``
    (``(columns,)`` or ``(frames, columns)``, the last one the frame before the block). With ``ghosts``:
    ``(columns, 1 + GHOST_LEVELS)``, the first knot then each lifting level ``l``'s ghost, the decoded value
    ``2 ** (l + 1)`` frames before that frame (rotations unwrapped from the first knot; NaN where ``before`` does
    not reach), from which :mod:`.lifting` predicts the level's first detail with the 4-point filter as inside a
    clip: the block meets the one before it without a kink. (On a model base the residual of that frame is not
    the block's: the model's own first knot codes smaller there.)"""
    frames = np.atleast_2d(np.asarray(before, dtype=np.float64))
    raw = frames[-1]
    r = raw.copy()
    half = period / 2
    if rot.any():
        r[rot] = np.mod(r[rot] + half, period) - half
    first = np.where(np.isfinite(r), r + 0.0, np.nan)
    if not ghosts:
        return first
    out = np.full((first.size, 1 + GHOST_LEVELS), np.nan)
    out[:, 0] = first
    for level in range(GHOST_LEVELS):
        back = 1 << (level + 1)
        if back >= frames.shape[0]:
            break
        d = frames[-1 - back] - raw
        if rot.any():
            d[rot] = np.mod(d[rot] + half, period) - half
        g = first + d
        out[:, 1 + level] = np.where(np.isfinite(g), g, np.nan)
    return out


def kept_layout(ctx: BlockOf, lay: Layout) -> Layout:
    """A stream's block's column layout: the one a block before it used, where that is safe for this block's
    frames (:func:`~.bounds.covers`: the tolerance codes then repeat, and are written once), else its own, kept
    for the blocks after it (in ``cache["stream"]``, which lasts the stream); a file's block's own."""
    kept = ctx.cache.get("stream")
    if kept is None:
        return lay
    old = kept.get("layout")
    if old is not None and covers(old, lay):
        return old
    kept["layout"] = lay
    return lay


def body_height(a: np.ndarray, valid: np.ndarray) -> float:
    """Median over frames of the body's largest extent (file units; 1 for an empty clip)."""
    if not a.size:
        return 1.0
    if valid.all() and np.isfinite(a).all():  # no gap: the same extents, point by point (NumPy reduces the
        hi, lo = a[:, 0].copy(), a[:, 0].copy()  # middle axis of a (frames, points, 3) array slowly)
        for p in range(1, a.shape[1]):
            np.maximum(hi, a[:, p], out=hi)
            np.minimum(lo, a[:, p], out=lo)
        h = float(np.median((hi - lo).max(axis=1)))
        return h if h > 0 else 1.0
    big = np.where(valid[..., None], a, np.nan)
    with np.errstate(invalid="ignore"):
        ext = np.nanmax(np.nanmax(big, axis=1) - np.nanmin(big, axis=1), axis=1)
    h = float(np.nanmedian(ext)) if np.isfinite(ext).any() else 1.0
    return h if h > 0 else 1.0
