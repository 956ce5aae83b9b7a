"""Planted feet in the correction layer: which groups hold a foot still, and how much speed a decoded foot adds.

The original's foot contacts (:func:`mocapz.metrics.contacts.find_contacts`, METRICS.md's height and speed
thresholds) say where a foot is planted; the encoder verifies the speed the decoded foot adds there (METRICS.md
``foot_skate``, frame to frame and over 0.1 s windows) and tightens the joints just above the foot, which the
closed loop (:mod:`.chain`) aims at the original below them, until it is small.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from mocapz.metrics.contacts import Contacts
from mocapz.metrics.skate import full_windows, horizontal_speeds, window_steps
from mocapz.model.motion import AnyMotion, Motion


def foot_groups(motion: AnyMotion, contacts: Contacts | None, positions: np.ndarray, n_groups: int,
                reach: float, aimed: np.ndarray | None = None) -> np.ndarray:
    """``(groups,)`` True on the joints above each foot point, up to and including the first with channels that
    is ``reach`` (file units) or farther from it over the clip (median) and that the closed loop aims (``aimed``
    ``(joints,)``, :attr:`.chain.Chain.feedback`: coded against its decoded parent, such a joint takes back the
    errors of the joints above it; None: any joint). The knee on a human leg whatever the joints between (CMU
    BVH: toe, ankle, knee; an ASF with a mid-foot joint: one more); the hip where the knee turns about one axis
    (CMU's ASF/AMC: toes, foot, tibia, femur): such a knee aims its bone about that axis only (:mod:`.hinge`)
    and lets the errors above it through. Markers: the foot markers. ``positions`` ``(frames, points, 3)`` is
    the original's."""
    out = np.zeros(n_groups, dtype=bool)
    if contacts is None:
        return out
    if not isinstance(motion, Motion):
        out[contacts.feet] = True
        return out
    sk = motion.skeleton
    for f in contacts.feet:
        j = int(sk.point_parents[f])
        while j >= 0:
            out[j] = True
            far = float(np.median(np.linalg.norm(positions[:, j] - positions[:, f], axis=1))) >= reach
            if far and sk.channels[j] and (aimed is None or aimed[j]):
                break
            j = int(sk.parents[j])
    return out


Carried = dict[tuple[int, int], tuple[float, int]]  # (window steps, foot point) -> (summed added speed, windows)
Before = tuple[np.ndarray, np.ndarray, np.ndarray]  # frames before a block: decoded, original, planted steps


def added_speed(contacts: Contacts | None, original: np.ndarray, pos: np.ndarray, fps: float,
                limit: float, carried: Carried | None = None, before: Before | None = None
                ) -> tuple[float, np.ndarray]:
    """The largest mean horizontal speed decoded positions ``pos`` add to a planted foot of the ``original``
    (both ``(frames, points, 3)``, file units), over each foot's planted steps, frame to frame and over 0.1 s
    windows (file units per second), and ``(frames, points)`` True on the foot samples whose added speed,
    largest first, makes up what is over ``limit`` (to bring it to half the limit). ``carried``: the blocks
    before this one in a stream (:func:`speed_sums`): a foot then passes when its mean over the block or over
    the stream so far (METRICS.md takes it over the whole file) is within the limit, either keeping the
    stream's within it, and the samples to tighten make up the smaller excess (only this block's samples: a
    stream whose mean sits at the limit is not asked to bring a long past down to half of it). ``before``: a
    block's frames before it as decoded (:func:`.context.feet_before`): the windows across its first edge count."""
    out = np.zeros(pos.shape[:2], dtype=bool)
    worst = 0.0
    for w, f, idx, excess, pre in _planted(contacts, original, pos, fps, before):
        own = float(excess[idx].mean())  # the block's own mean
        added, need = own, (own - 0.5 * limit) * idx.size
        if carried is not None:  # either mean within the limit will do (each keeps the stream's so far within it)
            s0, n0 = carried.get((w, int(f)), (0.0, 0))
            so_far = (s0 + float(excess[idx].sum())) / (n0 + idx.size)
            added, need = min(own, so_far), min(need, (so_far - 0.5 * limit) * (n0 + idx.size))
        worst = max(worst, added)
        if added <= limit:
            continue
        order = idx[np.argsort(-excess[idx])]
        n = int(np.searchsorted(np.cumsum(np.maximum(excess[order], 0.0)), need)) + 1
        for t in order[:n]:
            out[max(t - pre, 0) : t + w + 1 - pre, f] = True
    return worst, out


def speed_sums(contacts: Contacts | None, original: np.ndarray, pos: np.ndarray, fps: float,
               carried: Carried | None = None, before: Before | None = None) -> Carried:
    """``carried`` (empty: None) plus the added speed of ``pos`` summed over each foot's planted windows and
    their number, per window length (what :func:`added_speed` takes for the blocks after this one); ``before``
    as :func:`added_speed`'s."""
    out = dict(carried or {})
    for w, f, idx, excess, _ in _planted(contacts, original, pos, fps, before):
        s0, n0 = out.get((w, int(f)), (0.0, 0))
        out[(w, int(f))] = (s0 + float(excess[idx].sum()), n0 + int(idx.size))
    return out


def _planted(contacts: Contacts | None, original: np.ndarray, pos: np.ndarray, fps: float,
             before: Before | None = None) -> Iterator[tuple[int, int, np.ndarray, np.ndarray, int]]:
    """Per window length ``w`` (1 and 0.1 s) and foot point ``f`` with planted windows: ``(w, f, idx, excess,
    pre)``, the planted windows' first frames and the added speed ``(frames - w,)`` of every window, counted from
    the ``pre`` frames ``before`` the block (decoded, original, their planted steps into the block; 0 without):
    only the windows that reach a frame of the block (those wholly before it were the blocks' before)."""
    if contacts is None:
        return
    steps, pre = contacts.steps, 0
    if before is not None and before[0].shape[0]:
        pre = before[0].shape[0]
        pos, original = np.concatenate([before[0], pos]), np.concatenate([before[1], original])
        steps = np.concatenate([before[2], steps])
    if not steps.any() or pos.shape[0] < 3:
        return
    for w in sorted({1, window_steps(fps)}):
        if pos.shape[0] <= w:
            continue
        for i, f in enumerate(contacts.feet):
            full = full_windows(steps[:, i], w)
            full[:max(pre - w, 0)] = False
            if not full.any():
                continue
            excess = (horizontal_speeds(np.nan_to_num(pos[:, f]), contacts.horizontal, w, fps)
                      - horizontal_speeds(original[:, f], contacts.horizontal, w, fps))
            yield w, f, np.flatnonzero(full), excess, pre
