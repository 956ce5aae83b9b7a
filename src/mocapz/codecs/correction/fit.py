"""The encoder side of the correction layer: the residual between a model's decoded values and the original,
coded so that every point of every frame meets its position bound, verified by forward kinematics.

:class:`Clip` holds what does not depend on the model (original values and positions, the layout, the foot
contacts); :func:`fit` codes the residual of one decoded base for one position bound ``E`` and returns the
correction (its sections and the corrected positions); :func:`bound_search` finds the largest ``E`` that also
meets a distortion or ARMS target, and :func:`search` the lifting depth that codes the clip smallest.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import numpy as np

from mocapz.codecs.correction import bounds, context, feet, lifting
from mocapz.codecs.correction.chain import Chain
from mocapz.codecs.target import ErrorMetric, Errors, Target
from mocapz.format.entropy import encode_int_matrix, pack_uint64
from mocapz.metrics.contacts import find_contacts
from mocapz.model.kinematics import forward_kinematics
from mocapz.model.motion import AnyMotion, Motion

SKATE_CM_S = 0.3  # foot speed a planted foot may gain, frame to frame and over 0.1 s (cm/s; issue 11 allows 0.5)
FOOT_REACH = 0.2  # the joints above a foot tightened for its skate reach the first this far from it (a share of the
# body height: the knee), the closed loop aiming each at the original below it
FOOT_START = 2  # levels those joints start tighter than the others on planted frames
SHRINK = 0.85  # tolerance factor per lifting level (lifting.level_factor): smooth corrections, little jitter
WIDEN = 2  # frames tightened on each side of a miss
VERIFY = 1.0 - 1e-6  # verified against the bound less a hair (the decoder's angle wrapping, float rounding)
MAX_ROUNDS = 40  # verification rounds (each raises levels by one; the safe levels end it earlier)
SEARCH_FITS = 10
JITTER = 0.045  # added acceleration energy allowed (fraction of the original's), tightened beyond
JITTER_UP_TO_CM = 2.0  # targets up to this bound keep the added jitter under JITTER
JITTER_LEVELS = 8  # how far beyond the safe levels the jitter may tighten (2 ** 4 finer)


def value_matrix(motion: AnyMotion) -> np.ndarray:
    """The values the correction works on: ``(frames, columns)`` channels or marker coordinates (NaN gaps)."""
    if isinstance(motion, Motion):
        return np.asarray(motion.channels, dtype=np.float64)
    return motion.positions.reshape(motion.n_frames, 3 * motion.n_markers)


def rotation_period(motion: AnyMotion) -> tuple[np.ndarray, float]:
    """``(columns,)`` rotation mask and the full turn in the angle unit (markers: none, 0)."""
    if isinstance(motion, Motion):
        sk = motion.skeleton
        return sk.rotation_columns(), (360.0 if sk.angle_unit == "deg" else 2 * math.pi)
    return np.zeros(3 * motion.n_markers, dtype=bool), 0.0


def lifting_levels(frame_rate: float) -> int:
    """Lifting levels for a frame rate: coarse knots about a quarter of a second apart (1 to 6 levels)."""
    return int(min(6, max(1, round(math.log2(max(frame_rate, 2.0) / 4.0)))))


@dataclass
class Correction:
    """One coded correction: ``sections`` (``c.*``), its ``size`` in bytes, the corrected positions
    ``(frames, points, 3)``, their figures, the bound ``e`` it was made for and its added acceleration
    energy (``jitter``, a fraction)."""

    sections: dict[str, bytes]
    size: int
    positions: np.ndarray
    errors: Errors
    bound: float
    jitter: float = 0.0
    added: float = 0.0  # acceleration energy added (file units squared, summed over frames and points)
    depth: int = 0  # lifting levels (knots 2 ** depth frames apart)


class Clip:
    """The original clip as the correction sees it.

    Args:
        motion: the original.
        hold_feet: keep planted feet still on their contact frames (the speed they gain is verified,
            :meth:`skate`, at most :data:`SKATE_CM_S`).
    """

    def __init__(self, motion: AnyMotion, hold_feet: bool) -> None:
        self.motion = motion
        self.metric = ErrorMetric(motion)
        self.positions = self.metric.positions
        self.valid = np.ones(self.positions.shape[:2], dtype=bool) if self.metric.valid is None \
            else self.metric.valid
        self.values = value_matrix(motion)
        self.rot, self.period = rotation_period(motion)
        self.shrink = SHRINK
        self.chain = None
        if isinstance(motion, Motion) and motion.n_frames:
            self.chain = Chain(motion, self.positions, forward_kinematics(motion.skeleton, motion.channels)[1])
        levers = self.chain.levers(motion.channels) if self.chain is not None else None
        self.layout = bounds.layout(motion, self.positions, levers)
        self.levels = lifting_levels(motion.frame_rate)
        self.whole = context.block_of(motion)  # the clip this is a block of: decide as on the whole clip
        if not hold_feet:
            self.contacts = None
        elif self.whole is not None:
            self.contacts = context.contacts(self.whole)
        else:
            with warnings.catch_warnings():  # markers missing in every frame
                warnings.simplefilter("ignore", RuntimeWarning)
                self.contacts = find_contacts(motion, self.positions, self.valid, motion.unit_cm)
        self.body = body_height(self.positions, self.valid) if self.whole is None \
            else context.cached(self.whole, "body", body_height)

    def smooth_up_to(self) -> float:
        """The largest bound at which the added jitter is held under :data:`JITTER` (file units): 2 cm, or
        1/85 of the body height when the unit is unknown. Looser targets get the model's own smoothness."""
        unit = self.motion.unit_cm
        return JITTER_UP_TO_CM / unit if unit else self.body / 85.0

    def skate_limit(self) -> float:
        """:data:`SKATE_CM_S` in file units per second (1/340 of the body height per second when the unit is
        unknown)."""
        unit = self.motion.unit_cm
        return SKATE_CM_S / unit if unit else self.body * SKATE_CM_S / 170.0

    def held(self) -> np.ndarray:
        """``(frames, points)`` True on the planted feet's contact frames."""
        out = np.zeros(self.positions.shape[:2], dtype=bool)
        if self.contacts is not None and self.contacts.feet.size:
            out[:, self.contacts.feet] = self.contacts.frames()
        return out

    def foot_groups(self) -> np.ndarray:
        """``(groups,)`` True on the groups that hold a foot still (:func:`.feet.foot_groups`)."""
        return feet.foot_groups(self.motion, self.contacts, self.positions, self.layout.n_groups,
                                FOOT_REACH * self.body)

    def skate(self, pos: np.ndarray) -> tuple[float, np.ndarray]:
        """The largest speed decoded positions ``(frames, points, 3)`` add to a planted foot and the samples to
        tighten (:func:`.feet.added_speed`)."""
        return feet.added_speed(self.contacts, self.positions, pos, float(self.motion.frame_rate),
                                self.skate_limit())

    def point_bounds(self, e: float) -> np.ndarray:
        """``(frames, points)`` position bounds: ``e`` on every point (planted feet are held by their speed,
        :meth:`skate`)."""
        return np.full(self.positions.shape[:2], e)

    def residual(self, base: np.ndarray) -> np.ndarray:
        """``(frames, columns)`` original minus decoded values (angles wrapped to the nearest turn; 0 where a
        sample is missing)."""
        r = self.values - base
        if self.rot.any():
            half = self.period / 2
            r[:, self.rot] = np.mod(r[:, self.rot] + half, self.period) - half
        return np.nan_to_num(r, nan=0.0, posinf=0.0, neginf=0.0)

    def jitter(self, pos: np.ndarray) -> tuple[float, np.ndarray]:
        """Added acceleration energy of decoded positions ``(frames, points, 3)`` (sum over frames and points of
        ``|second difference|^2``, decoded / original - 1) and ``(frames, points)`` True on the samples whose
        excess energy, largest first, makes up what is over :data:`JITTER`."""
        out = np.zeros(pos.shape[:2], dtype=bool)
        if pos.shape[0] < 3:
            return 0.0, out
        ea, ok = context.acceleration_energy(self.positions, self.valid)
        eb = np.where(ok, (np.diff(np.nan_to_num(pos), 2, axis=0) ** 2).sum(axis=2), 0.0)
        total = context.energy_reference(self.whole, float(ea.sum()), JITTER)
        if total <= 0:
            return 0.0, out
        jit = float(eb.sum()) / total - 1.0 if self.whole is None else (float(eb.sum()) - float(ea.sum())) / total
        if jit <= JITTER:
            return jit, out
        excess = (eb - ea).ravel()
        order = np.argsort(-excess)
        need = (jit - 0.5 * JITTER) * total  # bring it well under the limit
        n = int(np.searchsorted(np.cumsum(np.maximum(excess[order], 0.0)), need)) + 1
        hit = np.zeros(excess.size, dtype=bool)
        hit[order[:n]] = True
        hit = hit.reshape(eb.shape)
        out[1:-1] |= hit  # the second difference centred on frame t + 1 involves t, t + 1, t + 2
        out[:-2] |= hit
        out[2:] |= hit
        return jit, out

    def added_energy(self, pos: np.ndarray) -> float:
        """Acceleration energy decoded positions ``(frames, points, 3)`` add to the original's (0 without a
        clip around this block: nothing to account for)."""
        if self.whole is None or pos.shape[0] < 3:
            return 0.0
        ea, ok = context.acceleration_energy(self.positions, self.valid)
        eb = np.where(ok, (np.diff(np.nan_to_num(pos), 2, axis=0) ** 2).sum(axis=2), 0.0)
        return float(eb.sum()) - float(ea.sum())

    def quantise(self, x: np.ndarray, base: np.ndarray, tol: np.ndarray, depth: int) -> tuple[np.ndarray, np.ndarray]:
        """The residual ``x`` of decoded ``base`` values quantised within ``tol`` (all ``(frames, columns)``):
        in closed loop down the hierarchy for skeletons (:mod:`.chain`)."""
        if self.chain is not None:
            return self.chain.quantise(x, base, tol, depth, self.shrink)
        return lifting.quantise(x, tol, depth, self.shrink)

    def positions_of(self, values: np.ndarray) -> np.ndarray:
        """Positions ``(frames, points, 3)`` of decoded values ``(frames, columns)``."""
        if isinstance(self.motion, Motion):
            return forward_kinematics(self.motion.skeleton, values)[0]
        return values.reshape(self.positions.shape)

    def precision_floor(self) -> float:
        """The largest position error the source's own decimals allow (file units; 0 when unknown)."""
        dec = self.motion.decimals
        if dec is None or not np.size(dec):
            return 0.0
        quantum = 0.5 * 10.0 ** -float(np.max(dec))  # the file's finest decimals: its precision
        # quantum / t_safe is the position error one column's rounding can cause (worst-case share)
        t_safe = self.layout.t_safe[self.layout.moving]
        per_col = np.where(np.isfinite(t_safe), quantum / t_safe * bounds.SAFETY, 0.0)
        return float(per_col.max(initial=0.0))


def body_height(a: np.ndarray, valid: np.ndarray) -> float:
    """Median over frames of the body's largest extent (file units; 1 for an empty clip)."""
    if not a.size:
        return 1.0
    big = np.where(valid[..., None], a, np.nan)
    with np.errstate(invalid="ignore"):
        ext = np.nanmax(np.nanmax(big, axis=1) - np.nanmin(big, axis=1), axis=1)
    h = float(np.nanmedian(ext)) if np.isfinite(ext).any() else 1.0
    return h if h > 0 else 1.0


def fit(clip: Clip, base: np.ndarray, e: float, relax_by: float = bounds.RELAX, depth: int | None = None) -> Correction:
    """Code the residual of decoded base values ``(frames, columns)`` so that every point is within ``e``
    (file units), planted feet still and the added jitter small, verified on the corrected positions.
    ``relax_by``: the base tolerances' multiple of the worst-case-safe ones (the verification tightens
    where that is too much); ``depth``: lifting levels (default: the clip's, :func:`lifting_levels`)."""
    depth = clip.levels if depth is None else depth
    lay = clip.layout
    x = clip.residual(base)
    t0 = relax_by * lay.t_safe * e
    t0 = np.where(lay.moving, t0, relax_by * bounds.TINY * lay.t_safe * e)
    codes = bounds.code_for(t0)
    t0 = bounds.tol_of(codes)
    bound = clip.point_bounds(e)
    cap = bounds.safe_levels(lay, bound, e, relax_by)
    relax = int(math.ceil(2 * math.log2(relax_by)))
    # relaxed, a little tighter on the joints that hold the planted feet (their speed is verified below)
    feet = clip.foot_groups()
    tighter = bounds.groups_moving(lay, clip.held()) & feet[None, :]
    levels = np.where(tighter, np.maximum(cap - relax + FOOT_START, 0), np.maximum(cap - relax, 0))
    valid = clip.valid
    cap_jitter = cap + JITTER_LEVELS
    smooth = e <= clip.smooth_up_to()
    jit = 0.0
    for _ in range(MAX_ROUNDS):
        q, y = clip.quantise(x, base, bounds.tolerances(t0, lay, levels), depth)
        pos = clip.positions_of(base + y)
        with np.errstate(invalid="ignore"):
            err = np.linalg.norm(pos - clip.positions, axis=2)
        misses = valid & ~(err <= bound * VERIFY)
        limit, step, only = cap, 1, None
        if not misses.any() and smooth:  # every bound holds: then the added acceleration energy and foot speed
            jit, misses = clip.jitter(pos)
            limit, step = cap_jitter, 2
            if jit <= JITTER:
                skate, misses = clip.skate(pos)
                if skate <= clip.skate_limit():
                    break
                step, only = 1, feet
        if not misses.any():
            break
        if WIDEN and misses.any():  # tighten a few frames around each miss: fewer level changes, smoother
            grown = misses.copy()
            for k in range(1, WIDEN + 1):
                grown[k:] |= misses[:-k]
                grown[:-k] |= misses[k:]
            misses = grown
        if not bounds.tighten(levels, limit, lay, misses, step, only) and (
                only is None or not bounds.tighten(levels, limit, lay, misses, step)):  # then every joint above
            break
    q, y, pos = _settle(clip, x, base, t0, levels, cap, bound, depth)
    sections = {
        "c.codes": pack_uint64(codes.astype(np.uint64)),
        "c.levels": encode_int_matrix(np.diff(levels, axis=0, prepend=0)),
        "c.res": lifting.pack(q, x.shape[0], depth),
    }
    size = sum(len(v) + 8 for v in sections.values())
    return Correction(sections, size, pos, clip.metric.of_positions(pos), e, jit, clip.added_energy(pos), depth)


def _settle(clip: Clip, x: np.ndarray, base: np.ndarray, t0: np.ndarray, levels: np.ndarray, cap: np.ndarray,
            bound: np.ndarray, depth: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The last word on the bound: the rounds of :func:`fit` may end (jitter tightening undoing a bound met one
    round before) with a few points over their bound; the groups acting on them go straight to their safe
    level, where the worst-case sum holds, until none is over (at worst every group at its safe level).
    Returns the integers, the decoded residual and the corrected positions; ``levels`` is raised in place."""
    lay = clip.layout
    for _ in range(MAX_ROUNDS):
        q, y = clip.quantise(x, base, bounds.tolerances(t0, lay, levels), depth)
        pos = clip.positions_of(base + y)
        with np.errstate(invalid="ignore"):
            misses = clip.valid & ~(np.linalg.norm(pos - clip.positions, axis=2) <= bound * VERIFY)
        if not misses.any():
            break
        up = bounds.groups_moving(lay, misses) & (levels < cap)
        if not up.any():
            up = levels < cap  # nothing left to raise where it misses: every group to its safe level
            if not up.any():
                break
        levels[up] = cap[up]
    return q, y, pos


RELAXES = (16.0,)  # relax_by tried: how far errors fall short of the worst case (8, 11.3, 22.6 and 32 gave
# larger files on the CMU clips)
DEPTHS = (0, -1, -2)  # lifting levels tried, added to the clip's (knots a quarter, an eighth, a sixteenth of a
# second apart: which codes a clip smallest depends on its motion)
SAMPLE_S = 6.0  # a long clip's settings are chosen on two windows of this many seconds, then coded whole


def search(clip: Clip, base: np.ndarray, target: Target, depth: int | None = None) -> Correction:
    """The smallest correction meeting ``target``: each setting of :data:`RELAXES` x :data:`DEPTHS` is tried
    with :func:`bound_search` (on two windows of a long clip: a prediction, then the chosen setting is coded
    and verified on the whole clip; should it miss, the first setting is). ``depth``: the lifting depth, when
    known (e.g. chosen on another base of the same clip)."""
    depths = [depth] if depth is not None else [max(1, clip.levels + d) for d in DEPTHS]
    settings = list(dict.fromkeys((r, dp) for dp in depths for r in RELAXES))
    parts = _windows(clip, base)
    if parts[0][0] is clip:
        tried = [bound_search(clip, base, target, r, dp) for r, dp in settings]
        met = [c for c in tried if target.met(c.errors)]
        return min(met, key=lambda c: c.size) if met else tried[0]
    sizes = [sum(bound_search(c, b, target, r, dp).size for c, b in parts) for r, dp in settings]
    chosen = settings[int(np.argmin(sizes))]
    best = bound_search(clip, base, target, *chosen)
    if not target.met(best.errors) and chosen != settings[0]:
        best = bound_search(clip, base, target, *settings[0])
    return best


def _windows(clip: Clip, base: np.ndarray) -> list[tuple[Clip, np.ndarray]]:
    """The clip itself, or for a long clip (over three windows of :data:`SAMPLE_S`; not a block, whose
    decisions are the whole clip's) two windows centred at a third and two thirds of it."""
    motion = clip.motion
    w = max(256, int(SAMPLE_S * motion.frame_rate))
    n = motion.n_frames
    if n <= 3 * w or clip.whole is not None:
        return [(clip, base)]
    out = []
    for centre in (n // 3, 2 * n // 3):
        a = max(0, centre - w // 2)
        sub = motion.slice(a, a + w)
        sub = replace(sub, metadata={k: v for k, v in sub.metadata.items() if k != "block_of"})
        out.append((Clip(sub, clip.contacts is not None), base[a:a + w]))
    return out


def bound_search(clip: Clip, base: np.ndarray, target: Target, relax_by: float, depth: int) -> Correction:
    """The correction with the largest bound meeting ``target`` (the bound is at most ``max_error``; for a
    distortion or ARMS target, secant steps in log space inside the bracket of met and missed bounds, at most
    :data:`SEARCH_FITS` fits)."""
    e_cap = target.max_error
    if target.max_distortion is None and target.max_arms is None:
        assert e_cap is not None
        return fit(clip, base, e_cap, relax_by, depth)
    guesses = []
    if target.max_arms is not None:
        guesses.append(2.0 * target.max_arms)
    if target.max_distortion is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            present = np.where(clip.valid[..., None], clip.positions, np.nan)
            spread = float(np.nan_to_num(np.sqrt(np.nanmean((present - np.nanmean(present, axis=0)) ** 2) * 3)))
        guesses.append(2.0 * target.max_distortion / 100.0 * max(spread, 1e-12))
    base_errors = clip.metric.of_positions(clip.positions_of(base))
    if target.met(base_errors) and base_errors.max_error > 0:  # the model alone meets it: hold feet, bound the rest
        guesses = [base_errors.max_error * 1.001]
    e = min(guesses + ([e_cap] if e_cap is not None else []))
    best: Correction | None = None  # the largest bound met so far
    low_fail = math.inf  # the smallest bound missed so far
    cur = fit(clip, base, e, relax_by, depth)
    for _ in range(SEARCH_FITS):
        score = target.score(cur.errors)
        if score <= 1:
            best = cur if best is None or cur.bound > best.bound else best
        else:
            low_fail = min(low_fail, cur.bound)
        # secant in log space (the figures grow about linearly with the bound), kept inside the bracket
        nxt = cur.bound * float(np.clip(0.95 / max(score, 1e-9), 0.25, 4.0))
        if e_cap is not None:
            nxt = min(nxt, e_cap)
        lo = best.bound if best is not None else 0.0
        if not lo < nxt < low_fail:
            nxt = math.sqrt(lo * low_fail) if lo > 0 and math.isfinite(low_fail) else (
                lo * 2.0 if lo > 0 else low_fail / 2.0)
        if (best is not None and (nxt <= best.bound * 1.08 or (e_cap is not None and best.bound >= e_cap)))\
                or (math.isfinite(low_fail) and nxt >= low_fail / 1.08 and best is not None):
            break
        cur = fit(clip, base, nxt, relax_by, depth)
    return best if best is not None else cur
