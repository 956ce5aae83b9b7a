"""The verification rounds of the correction's fit (:func:`.fit.fit`): the residual coded at the current tolerance
levels, the decoded positions checked against every point's bound, the planted feet's added speed and the added
jitter, and the levels raised where something is over, until nothing is (:func:`rounds`); then the last word on the
bounds (:func:`_settle`). ``levels`` are ``(frames, groups)`` tightening steps (each halves a tolerance's square:
:func:`.bounds.tolerances`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from mocapz.codecs.correction import bounds
from mocapz.format.entropy import encode_int_matrix
from mocapz.metrics.figures import point_errors

WIDEN = 2  # frames tightened on each side of a miss
STALLED = 0.9  # feet whose added speed fell by less than this factor in a round: every joint above them tightened
VERIFY = 1.0 - 1e-6  # verified against the bound less a hair (the decoder's angle wrapping, float rounding)
MAX_ROUNDS = 40  # verification rounds (each raises levels by one; the safe levels end it earlier)
JITTER_LEVELS = 8  # how far beyond the safe levels the jitter may tighten (2 ** 4 finer)


Clip = Any  # a :class:`.fit.Clip` (which imports this module)
Coding = tuple[np.ndarray, np.ndarray, np.ndarray]  # integers, decoded residual, decoded positions


def rounds(clip: Clip, x: np.ndarray, base: np.ndarray, t0: np.ndarray, levels: np.ndarray, cap: np.ndarray,
           bound: np.ndarray, depth: int, feet: np.ndarray, smooth: bool, give_up: float = math.inf,
           packed: Callable[[np.ndarray], bytes] | None = None) -> tuple[Coding, float, bool] | None:
    """The verification rounds of :func:`.fit.fit` (``levels`` ``(frames, groups)`` raised in place, at most to
    ``cap``, or beyond for the jitter and the feet), then :func:`_settle`: the coding, the added jitter and
    whether the rounds settled (False: :data:`MAX_ROUNDS` ran out, e.g. a planted foot's speed swinging around
    its limit while the jitter tightens every joint). What
    a round makes is let go before the next round codes (and all of it on return: peak memory).

    None where a round's integers alone, entropy coded, reach ``give_up`` bytes (the rounds only raise levels,
    finer steps, larger integers: the correction's sections would come to more, and the file on this base could not
    be the smaller one): checked on the first round's integers and on every later round's whose estimate reaches
    ``give_up``, packed by ``packed`` as the correction's ``c.res`` would be (:class:`_GiveUp`)."""
    lay, valid = clip.layout, clip.valid
    reaches = _GiveUp(give_up, packed or encode_int_matrix) if math.isfinite(give_up) else None
    jit = 0.0
    last = None  # the coding of the current levels
    slid = math.inf  # the feet's added speed the round before
    settled = False
    for _ in range(MAX_ROUNDS):
        q, y, pos = last = clip.quantise(x, base, bounds.tolerances(t0, lay, levels), depth)
        if reaches is not None and reaches(q):
            return None
        with np.errstate(invalid="ignore"):
            err = point_errors(pos, clip.positions)
        misses = valid & ~(err <= bound * VERIFY)
        del err
        # what to tighten this round, each (samples, levels cap, step, groups allowed): the points over their
        # bound, or once every bound holds the added acceleration energy; and the planted feet's added speed
        # in the same round (it is mostly the joints above the feet: tightening them with the rest halves the
        # rounds)
        todo: list[tuple[np.ndarray, np.ndarray, int, np.ndarray | None]] = []
        if misses.any():
            todo.append((misses, cap, 1, None))
        elif smooth:
            jit, shaky = clip.jitter(pos)
            if shaky.any():
                todo.append((shaky, cap + JITTER_LEVELS, 2, None))
        skate, sliding = clip.skate(pos, base)
        if skate > clip.skate_limit() and sliding.any():  # the joints above the feet, or every joint above them
            allowed = feet if skate < STALLED * slid else None  # if that did not help
            todo.append((sliding, cap + JITTER_LEVELS, 1, allowed))
            slid = skate
        moved = False
        for samples, limit, step, only in todo:
            samples = _widen(samples)
            moved |= bounds.tighten(levels, limit, lay, samples, step, only) or (
                only is not None and bounds.tighten(levels, limit, lay, samples, step))  # then every joint above
        if not moved:
            settled = True
            break
        # this round's coding is done with: the next one is made without it beside (peak memory)
        last = None
        del q, y, pos, misses, todo, samples
    coding = _settle(clip, x, base, t0, levels, cap, bound, depth, last, reaches)
    return None if coding is None else (coding, jit, settled)


class _GiveUp:
    """Whether a round's integers ``(n, columns)`` reach ``give_up`` bytes: the first round's entropy coded
    (:func:`~mocapz.format.entropy.encode_int_matrix`); a later round's estimated from the last bytes found,
    scaled by the integers' summed ``log2(1 + |q|)`` (which grows with their code lengths as the levels rise), and
    only where that estimate reaches ``give_up`` packed as the correction's ``c.res`` section would hold them
    (``packed``; a few tenths of a second on a 10-minute clip, once or twice): the other sections come on top, and
    later rounds only raise levels, so the file on this base could not be the smaller one."""

    def __init__(self, give_up: float, packed: Callable[[np.ndarray], bytes]) -> None:
        self.give_up, self.packed = give_up, packed
        self.found: tuple[int, float] | None = None  # the last bytes found and the integers' summed log2(1 + |q|)

    def __call__(self, q: np.ndarray) -> bool:
        spread = _spread(q)
        if self.found is None:
            size = len(encode_int_matrix(q))
        elif self.found[0] * spread < self.give_up * self.found[1]:
            return False
        else:
            size = len(self.packed(q))
        self.found = (size, spread)
        return size >= self.give_up


def _spread(q: np.ndarray, rows: int = 4096) -> float:
    """The summed ``log2(1 + |q|)`` of integers ``(n, columns)``, by chunks of rows (no temporaries of their size)."""
    return float(sum(np.log2(1.0 + np.abs(q[a:a + rows])).sum() for a in range(0, q.shape[0], rows)))


def _widen(samples: np.ndarray) -> np.ndarray:
    """``(frames, points)`` samples to tighten, spread over :data:`WIDEN` frames on each side: a few frames
    tightened around each miss make fewer level changes, and smoother ones."""
    out = samples.copy()
    for k in range(1, WIDEN + 1):
        out[k:] |= samples[:-k]
        out[:-k] |= samples[k:]
    return out


def _settle(clip: Clip, x: np.ndarray, base: np.ndarray, t0: np.ndarray, levels: np.ndarray, cap: np.ndarray,
            bound: np.ndarray, depth: int, last: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
            reaches: _GiveUp | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The last word on the bound: the rounds of :func:`.fit.fit` may end (jitter tightening undoing a bound met one
    round before) with a few points over their bound; the groups acting on them go straight to their safe
    level, where the worst-case sum holds, until none is over (at worst every group at its safe level).
    Returns the integers, the decoded residual and the corrected positions; ``levels`` is raised in place.
    ``last``: the coding of ``levels`` as they are, when the caller has it; ``reaches``: the rounds' give-up check
    (None returned where a new coding's integers reach it)."""
    lay = clip.layout
    for round_ in range(MAX_ROUNDS):
        fresh = last is None
        q, y, pos = last if last is not None else clip.quantise(x, base, bounds.tolerances(t0, lay, levels), depth)
        last = None
        if fresh and reaches is not None and reaches(q):
            return None
        with np.errstate(invalid="ignore"):
            misses = clip.valid & ~(point_errors(pos, clip.positions) <= bound * VERIFY)
        if not misses.any():
            break
        up = bounds.groups_moving(lay, misses) & (levels < cap)
        if not up.any():
            up = levels < cap  # nothing left to raise where it misses: every group to its safe level
            if not up.any():
                break
        levels[up] = cap[up]
        if round_ + 1 < MAX_ROUNDS:  # this coding is not kept beside the next one (peak memory)
            del q, y, pos
    return q, y, pos
