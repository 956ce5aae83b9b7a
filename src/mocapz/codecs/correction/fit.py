"""The encoder side of the correction layer: the residual between a model's decoded values and the original,
coded so that every point of every frame meets its position bound, verified by forward kinematics.

:class:`Clip` holds what does not depend on the model (original values and positions, the layout, the foot
contacts); :func:`fit` codes the residual of one decoded base for one position bound ``E`` and returns the
correction (its sections and the corrected positions). :mod:`.search` chooses the bound and the settings.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mocapz._memory import release_free_memory
from mocapz.codecs.correction import bounds, context, energy, feet, lifting, window
from mocapz.codecs.correction.chain import Chain
from mocapz.codecs.correction.compiled import kernels, note_round
from mocapz.codecs.correction.rounds import JITTER_LEVELS, rounds
from mocapz.codecs.target import ErrorMetric, Errors
from mocapz.format.entropy import encode_int_matrix, pack_uint64
from mocapz.metrics.contacts import find_contacts
from mocapz.metrics.skate import window_steps
from mocapz.model.kinematics import forward_kinematics, forward_positions
from mocapz.model.motion import AnyMotion, Motion

SKATE_CM_S = 0.3  # foot speed a planted foot may gain, frame to frame and over 0.1 s (cm/s; issue 11 allows 0.5)
FOOT_REACH = 0.2  # the joints above a foot tightened for its skate reach the first this far from it (a share of the
# body height: the knee) that the closed loop aims at the original below it (a one-axis knee: the hip)
FOOT_START = 2  # levels those joints start tighter than the others on planted frames
SHRINK = 0.85  # tolerance factor per lifting level (lifting.level_factor): smooth corrections, little jitter
JITTER_UP_TO_CM = 2.0  # targets up to this bound keep the added jitter under JITTER
GAVE_UP = 1 << 62  # the bytes of a correction given up (:func:`fit`'s ``give_up``): never the smaller
HANDOVER_LEVELS = 2  # a skeleton stream block's last frame, which the next block continues from: this much tighter
# (half the tolerance; Clip.handover)


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
    """One coded correction: its sections (``c.*``) and their ``size`` in bytes, the figures of the corrected
    positions, the bound ``e`` it was made for and its added acceleration energy (``jitter``, a fraction). The
    corrected positions themselves are not kept (a clip's worth of memory per correction). ``made``: the
    sections, or what packs them when they are first asked for (:func:`fit`'s ``lazy``: a bound search packs only
    the correction it keeps, not every one it tries)."""

    made: dict[str, bytes] | Callable[[], dict[str, bytes]]
    errors: Errors
    bound: float
    jitter: float = 0.0
    added: float = 0.0  # acceleration energy added (file units squared, summed over frames and points)
    skated: feet.Carried | None = None  # a block's: the feet's added speed so far (:func:`.feet.speed_sums`)
    depth: int = 0  # lifting levels (knots 2 ** depth frames apart)
    settled: bool = True  # the verification rounds ended before MAX_ROUNDS (False: they ran out, levels high)
    tail: context.Edge | None = None  # a block's: its last frames (:func:`.context.tail`), the next block's edge
    gave_up: bool = False  # given up (:func:`fit`'s ``give_up``): no sections, :data:`GAVE_UP` bytes

    @property
    def sections(self) -> dict[str, bytes]:
        """The ``c.*`` sections (packed now if they were not yet; what packed them is let go)."""
        if callable(self.made):
            self.made = self.made()
        return self.made

    @property
    def size(self) -> int:
        """Bytes of the sections, each counted with 8 bytes of its name and length (:data:`GAVE_UP` if given up)."""
        return GAVE_UP if self.gave_up else sum(len(v) + 8 for v in self.sections.values())


class Clip:
    """The original clip as the correction sees it.

    Args:
        motion: the original.
        hold_feet: keep planted feet still on their contact frames (the speed they gain is verified,
            :meth:`skate`, at most :data:`SKATE_CM_S`).
    """

    def __init__(self, motion: AnyMotion, hold_feet: bool) -> None:
        self.motion = motion
        fk = forward_kinematics(motion.skeleton, motion.channels) if isinstance(motion, Motion) and motion.n_frames \
            else None  # positions and global rotations, computed once for the metric and the closed loop
        self.metric = ErrorMetric(motion, None if fk is None else fk[0])
        self.positions = self.metric.positions
        self.valid = np.ones(self.positions.shape[:2], dtype=bool) if self.metric.valid is None \
            else self.metric.valid
        self.values = value_matrix(motion)
        self.rot, self.period = rotation_period(motion)
        self.shrink = SHRINK
        self.chain = None
        if fk is not None:
            self.chain = Chain(motion, self.positions, fk[1])  # keeps the feedback joints' rotations only
        del fk  # the other joints' global rotations are not kept (peak memory)
        self.whole = context.block_of(motion)  # the clip this is a block of: decide as on the whole clip
        # a stream's block continuing the one before it (short layout, zero base): the frame before, its first knot
        self.before = None if window.seekable(motion.n_frames) else context.continued(self.whole)
        self._zero: np.ndarray | None = None  # the zero base (:meth:`zero_base`)
        # frames of the whole job (a block's clip, a stream's window): whether the compiled kernels pay for loading
        self.work = motion.n_frames if self.whole is None else max(motion.n_frames, self.whole.clip.n_frames)
        if self.chain is not None:
            self.chain.work = self.work
        self.layout = self._layout()
        self.levels = lifting_levels(motion.frame_rate)
        if not hold_feet:
            self.contacts = None
        elif self.whole is not None:
            self.contacts = context.contacts(self.whole)
        else:
            with warnings.catch_warnings():  # markers missing in every frame
                warnings.simplefilter("ignore", RuntimeWarning)
                self.contacts = find_contacts(motion, self.positions, self.valid, motion.unit_cm)
        self.body = context.body_height(self.positions, self.valid) if self.whole is None \
            else context.cached(self.whole, "body", context.body_height)

    def _layout(self) -> bounds.Layout:
        """The clip's layout; a block's is the whole clip's (its levers and moving columns: safe for every
        block, and the step codes come out the same in every block, written once by the block marks)."""
        chain, whole = self.chain, self.whole
        if whole is None:
            return bounds.layout(self.motion, self.positions,
                                 chain.levers(self.motion.channels) if chain is not None else None)
        clip = whole.clip
        return context.kept_layout(whole, context.cached(whole, "layout", lambda pos, _: bounds.layout(
            clip, pos, chain.levers(clip.channels) if chain is not None else None)))

    def smooth_up_to(self) -> float:
        """The largest bound at which the added jitter is held under :data:`.energy.JITTER` (file units): 2 cm, or
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
                                FOOT_REACH * self.body, None if self.chain is None else self.chain.feedback)

    def skate(self, pos: np.ndarray, base: np.ndarray) -> tuple[float, np.ndarray]:
        """The largest speed decoded positions ``(frames, points, 3)`` on ``base`` add to a planted foot and the
        samples to tighten (:func:`.feet.added_speed`)."""
        return feet.added_speed(self.contacts, self.positions, pos, float(self.motion.frame_rate),
                                self.skate_limit(), context.carried_skate(self.whole), self.feet_before(base))

    def skate_sums(self, pos: np.ndarray, base: np.ndarray) -> feet.Carried | None:
        """A block's: the feet's added speed of decoded positions ``(frames, points, 3)`` on ``base`` summed with
        the blocks' before (:func:`.feet.speed_sums`); None for a clip of its own."""
        return None if self.whole is None else feet.speed_sums(
            self.contacts, self.positions, pos, float(self.motion.frame_rate), context.carried_skate(self.whole),
            self.feet_before(base))

    def feet_before(self, base: np.ndarray) -> feet.Before | None:
        """The frames before a block on a model ``base`` (it starts afresh: :func:`.context.feet_before`)."""
        model = self.contacts is not None and base is not self._zero
        return context.feet_before(self.whole, window_steps(self.motion.frame_rate)) if model else None

    def point_bounds(self, e: float) -> np.ndarray:
        """``(frames, points)`` position bounds: ``e`` on every point (planted feet are held by their speed,
        :meth:`skate`); a read-only view of the one value."""
        return np.broadcast_to(np.float64(e), self.positions.shape[:2])

    def residual(self, base: np.ndarray) -> np.ndarray:
        """``(frames, columns)`` original minus decoded values (angles wrapped to the nearest turn; 0 where a
        sample is missing), column-major: the rounds work a joint's columns at a time (:mod:`.chainround`)."""
        r = np.subtract(self.values, base, out=np.empty(self.values.shape, np.result_type(self.values, base), "F"))
        if self.rot.any():
            half = self.period / 2
            w = r[:, self.rot]
            w += half
            np.mod(w, self.period, out=w)
            w -= half
            r[:, self.rot] = w
        return np.nan_to_num(r, copy=False, nan=0.0, posinf=0.0, neginf=0.0)

    def jitter(self, pos: np.ndarray) -> tuple[float, np.ndarray]:
        """The added jitter of decoded positions ``(frames, points, 3)`` and the samples to tighten
        (:func:`.energy.jitter`)."""
        return energy.jitter(self.whole, self.positions, self.valid, pos)

    def added_energy(self, pos: np.ndarray) -> float:
        """Acceleration energy decoded positions ``(frames, points, 3)`` add to the original's (a block's;
        :func:`.energy.added`)."""
        return energy.added(self.whole, self.positions, self.valid, pos)

    def quantise(self, x: np.ndarray, base: np.ndarray, tol: np.ndarray | bounds.ColumnTolerances,
                 depth: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The residual ``x`` of decoded ``base`` values quantised within ``tol`` (all ``(frames, columns)``; the
        tolerances dense or per column): in closed loop down the hierarchy for skeletons (:mod:`.chain`, which
        writes the feedback joints' residuals into ``x``). Returns the integers, the decoded residual (not to be
        changed: the closed loop keeps it for its next call) and the decoded positions ``(frames, points, 3)``."""
        prefix = self.prefix_of(base)
        note_round(x.shape[0])
        if self.chain is not None:
            return self.chain.quantise(x, base, tol, depth, self.shrink, prefix)
        q, y = lifting.quantise(x, np.asarray(tol), depth, self.shrink, kernels(self.work, "liftkernels") is not None,
                                prefix)
        return q, y, self.positions_of(base + y)

    def of_job(self, frames: int) -> Clip:
        """This clip as a part of a job of ``frames`` frames (a long clip's window): its kernels as the job's."""
        self.work = max(self.work, frames)
        if self.chain is not None:
            self.chain.work = self.work
        return self

    def zero_base(self) -> np.ndarray:
        """The zero base ``(frames, columns)``: a read-only view of one zero (no frames x columns array)."""
        self._zero = np.broadcast_to(np.zeros((), self.values.dtype), self.values.shape) if self._zero is None \
            else self._zero
        return self._zero

    def handover(self, base: np.ndarray) -> bool:
        """Whether the clip is a skeleton stream's block on the zero base (the correction alone) that the next one
        continues: its last frame, the next block's first knot, is coded :data:`HANDOVER_LEVELS` tighter. The
        error the next block inherits there reaches every point below a joint through its levers, and a block
        that starts near its bound has no room to ease out of it: it pulls its first frames onto the original, a
        kink the jitter's rounds then pay for (on markers, whose errors stay on their own points, the tighter
        knot cost more than it saved: the shared files' marker streams +4.5 %, their skeletons' -4.8 %)."""
        return isinstance(self.motion, Motion) and base is self._zero and context.followed(self.whole)

    def prefix_of(self, base: np.ndarray) -> np.ndarray | None:
        """A continued block's first knot on ``base`` (:func:`.context.prefix`; the zero base only), else None."""
        if self.before is None or base is not self._zero:
            return None
        return context.prefix(self.before, self.rot, self.period, np.ndim(self.before) == 2)

    def positions_of(self, values: np.ndarray) -> np.ndarray:
        """Positions ``(frames, points, 3)`` of decoded values ``(frames, columns)``."""
        if isinstance(self.motion, Motion):
            return forward_positions(self.motion.skeleton, values)
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


def fit(clip: Clip, base: np.ndarray, e: float, relax_by: float = bounds.RELAX, depth: int | None = None,
        give_up: float = math.inf, lazy: bool = False) -> Correction:
    """Code the residual of decoded base values ``(frames, columns)`` so that every point is within ``e``
    (file units), planted feet still and the added jitter small, verified on the corrected positions.
    ``relax_by``: the base tolerances' multiple of the worst-case-safe ones (the verification tightens
    where that is too much); ``depth``: lifting levels (default: the clip's, :func:`lifting_levels`).
    ``give_up``: bytes the correction cannot be smaller than and be worth having (another base's file is): where
    its first round already reaches them (:func:`.rounds.rounds`), a correction of :data:`GAVE_UP` bytes that
    meets nothing comes back, no sections."""
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
    levels = np.asfortranarray(np.where(tighter, np.maximum(cap - relax + FOOT_START, 0), np.maximum(cap - relax, 0)))
    del tighter
    if clip.handover(base):
        levels[-1] = np.minimum(levels[-1] + HANDOVER_LEVELS, cap[-1] + JITTER_LEVELS)
    frames = x.shape[0]
    seek = window.seekable(frames)  # a long clip: its streams laid out for random access (c.head format 3)

    def packed(q: np.ndarray) -> bytes:  # the c.res section of integers q
        return window.pack_res(q, frames, depth) if seek else lifting.pack(q, frames, depth, clip.prefix_of(base),
                                                                           lay.group)

    done = rounds(clip, x, base, t0, levels, cap, bound, depth, feet, e <= clip.smooth_up_to(), give_up, packed)
    if clip.chain is not None:
        clip.chain.forget()  # what the rounds shared
    if done is None:
        return Correction({}, Errors(math.inf, math.inf, math.inf), e, depth=depth, gave_up=True)
    (q, y, pos), jit, settled = done
    del x, y, cap  # what is left to do needs the positions' figures and the integers only
    errors, added = clip.metric.of_positions(pos), clip.added_energy(pos)
    skated = clip.skate_sums(pos, base)
    tail = None if clip.whole is None else context.tail(context.before_block(clip.whole), pos, clip.positions,
                                                         clip.valid, window_steps(clip.motion.frame_rate))
    del pos  # the integers are packed without it (the entropy coders' work space comes on top)

    def sections(q: np.ndarray, levels: np.ndarray) -> dict[str, bytes]:
        release_free_memory()  # the rounds' freed arrays, not beside zstd's work space (mmap-ed, level 19)
        return {
            "c.codes": pack_uint64(codes.astype(np.uint64)),
            "c.levels": window.pack_levels(levels, frames, depth) if seek
            else encode_int_matrix(np.diff(levels, axis=0, prepend=0)),
            "c.res": packed(q),
        }

    if lazy:  # kept in the smallest integer types that hold them until packed (a search keeps one beside a fit)
        kept = [(_narrow(a), a.dtype) for a in (q, levels)]
        del q, levels
        return Correction(lambda: sections(*(a.astype(t) for a, t in kept)), errors, e, jit, added, skated, depth,
                          settled, tail)
    return Correction(sections(q, levels), errors, e, jit, added, skated, depth, settled, tail)


def _narrow(a: np.ndarray) -> np.ndarray:
    """Integers ``a`` in the smallest signed type that holds them (the same layout): the same numbers back with
    ``astype`` of ``a``'s type."""
    if a.size:
        lo, hi = int(a.min()), int(a.max())
        for t in (np.int8, np.int16, np.int32):
            if np.iinfo(t).min <= lo and hi <= np.iinfo(t).max:
                return a.astype(t)
    return a
