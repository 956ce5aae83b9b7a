"""Foot contacts of a motion: which points are feet, and in which frames a foot is planted.

Shared by the error figures (``foot_skate``, :mod:`mocapz.metrics.figures`) and by any encoder that keeps
planted feet still, so that both use METRICS.md's one definition: a foot is in contact when it is within
5 cm of its lowest height and moves slower than 50 cm/s (3 % of the body height and 30 % of the body
height per second when the length unit is unknown).

"Its lowest height" is the floor under the feet *now*: the lowest height of either foot over the last
:data:`FLOOR_WINDOW_S` seconds (this frame included), not over the whole clip (and not one foot's own: a raised
leg held still for seconds would be its own floor). A clip's single lowest sample
(a glitch, a foot through the floor, a step down from a stage or a slope) would otherwise decide every
contact: on CMU 06_13 one foot's end site dips 13 cm under the floor once and that foot had 23 planted steps
in 4,906 frames against 909 with the local floor. The window looks back only, so a stream that keeps the
last few seconds decides the same contacts as the whole file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapz.metrics.chunks import frame_chunks
from mocapz.model.motion import AnyMotion, Motion

CONTACT_HEIGHT_CM = 5.0
CONTACT_SPEED_CM_S = 50.0
FLOOR_WINDOW_S = 2.0  # seconds looked back for the floor under a foot


def floor_heights(h: np.ndarray, back: int) -> np.ndarray:
    """``(frames,)`` lowest value of ``h`` ``(frames,)`` over frames ``t - back`` to ``t`` (fewer at the start);
    missing samples as ``inf``."""
    if h.size == 0:
        return h.copy()
    # minima over trailing windows of 1, 2, 4, ... samples (before the first sample: h[0], which is in every
    # window that reaches it), then two overlapping windows of the largest power of two make back + 1: NumPy
    # only (scipy.ndimage costs every command 0.17 s to import), O(frames log back)
    out = np.asarray(h, dtype=np.float64).copy()
    span = 1
    while 2 * span <= back + 1:
        out = np.minimum(out, np.concatenate([np.full(span, out[0]), out[:-span]])[:out.size])
        span *= 2
    rest = back + 1 - span
    if rest:
        out = np.minimum(out, np.concatenate([np.full(rest, out[0]), out[:-rest]])[:out.size])
    return out


def up_axis(a: np.ndarray, valid: np.ndarray, points: np.ndarray | None = None) -> int:
    """Vertical axis of ``(frames, points, 3)`` positions (of their ``points`` only, if given): the one with the
    largest median per-frame extent of the body (height > width). The extents are taken a chunk of frames at a
    time (:data:`~mocapz.metrics.chunks.CHUNK_FRAMES`), each frame's as from the whole array."""
    sel = slice(None) if points is None else points
    ext = np.empty((a.shape[0], a.shape[2]))
    for t in frame_chunks(a.shape[0]):
        big = np.where(valid[t, sel, None], a[t, sel], np.nan)
        with np.errstate(invalid="ignore"):
            ext[t] = np.nanmax(big, axis=1) - np.nanmin(big, axis=1)
    return int(np.argmax(np.nanmedian(ext, axis=0)))


def foot_points(motion: AnyMotion, a: np.ndarray, valid: np.ndarray, up: int, pairs: int = 1) -> np.ndarray:
    """Indices of the two lowest points on average (the feet's end sites or toe markers); ``pairs`` 2: the four
    lowest, the lowest two first."""
    if isinstance(motion, Motion) and motion.skeleton.end_sites:
        cand = np.arange(motion.skeleton.n_joints, motion.skeleton.n_points)
    else:
        cand = np.arange(a.shape[1])
    with np.errstate(invalid="ignore"):
        h = np.nanmean(np.where(valid[:, cand], a[:, cand, up], np.nan), axis=0)
    h = np.where(np.isnan(h), np.inf, h)
    return cand[np.argsort(h)[:2 * pairs]]


@dataclass
class Contacts:
    """Planted-foot steps of a clip.

    Attributes:
        up: the vertical axis (0, 1 or 2).
        feet: ``(feet,)`` point indices of the feet (into the ``(frames, points, 3)`` positions).
        steps: ``(frames - 1, feet)`` True where the foot is planted over the step from frame t to t + 1
            (both samples present, low and slow in the original).
    """

    up: int
    feet: np.ndarray
    steps: np.ndarray

    @property
    def horizontal(self) -> list[int]:
        """The two horizontal axes."""
        return [k for k in range(3) if k != self.up]

    def frames(self) -> np.ndarray:
        """``(frames, feet)`` True on every frame that starts or ends a planted step."""
        f = np.zeros((self.steps.shape[0] + 1, self.steps.shape[1]), dtype=bool)
        f[:-1] |= self.steps
        f[1:] |= self.steps
        return f


def find_contacts(motion: AnyMotion, a: np.ndarray, valid: np.ndarray, unit_cm: float | None,
                  pairs: int = 1) -> Contacts:
    """The planted-foot steps of the original positions ``a`` ``(frames, points, 3)`` (file units),
    ``valid`` ``(frames, points)`` marking present samples. ``pairs`` 2: the two lowest pairs of points, each
    pair's steps as if it were the feet (its own floor): what a stream holds, which cannot know the pair the
    whole file's lowest two will be (a marker set's heels or its toes)."""
    # the body only: a static floor root far from the body (Bandai-Namco) must not make a walk's
    # direction look like the vertical
    body = motion.skeleton.body_points() if isinstance(motion, Motion) else np.arange(a.shape[1])
    up = up_axis(a, valid, body) if a.shape[0] else 1
    feet = foot_points(motion, a, valid, up, pairs) if a.shape[0] else np.zeros(0, dtype=np.int64)
    steps = np.zeros((max(a.shape[0] - 1, 0), feet.size), dtype=bool)
    if a.shape[0] < 2:
        return Contacts(up, feet, steps)
    fps = motion.frame_rate
    with np.errstate(invalid="ignore"):
        body = float(np.nanmedian(np.nanmax(np.where(valid, a[..., up], np.nan), axis=1)
                                  - np.nanmin(np.where(valid, a[..., up], np.nan), axis=1)))
    h_tol = CONTACT_HEIGHT_CM / unit_cm if unit_cm else 0.03 * body
    v_tol = CONTACT_SPEED_CM_S / unit_cm if unit_cm else 0.3 * body
    back = max(int(round(FLOOR_WINDOW_S * fps)), 1)
    for i, f in enumerate(feet):
        if i % 2 == 0:  # the floor is under both feet of a pair: a foot held up for seconds (a dancer's raised
            # leg) is not on its own minimum
            floor = np.min([floor_heights(np.where(valid[:, g], a[:, g, up], np.inf), back) for g in feet[i:i + 2]],
                           axis=0)
        pa, ok = a[:, f], valid[:, f]
        speed = np.linalg.norm(np.diff(pa, axis=0), axis=1) * fps
        with np.errstate(invalid="ignore"):
            low = pa[1:, up] <= floor[1:] + h_tol
            steps[:, i] = ok[1:] & ok[:-1] & low & (speed < v_tol)
    return Contacts(up, feet, steps)
