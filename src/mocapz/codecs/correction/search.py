"""The settings of the correction layer for a target: the position bound that meets a distortion or ARMS target
(:func:`bound_search`) and the lifting depth that codes the clip smallest (:func:`search`), each candidate
coded by :func:`.fit.fit` and verified.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from mocapz.codecs.correction.fit import Clip, Correction, fit
from mocapz.codecs.target import Target

SEARCH_FITS = 10  # fits a distortion or ARMS target's bound search makes at most
FLAT = 0.25  # a figure growing by less than this power of the bound is flat (:func:`_flat`): the base's own errors
LOOSEST = 8.0  # where the model alone meets the target, the bound goes up to this many times its largest error
RELAXES = (16.0,)  # relax_by tried: how far errors fall short of the worst case (8, 11.3, 22.6 and 32 gave
# larger files on the CMU clips)
DEPTHS = (0, -1, -2)  # lifting levels tried, added to the clip's (knots a quarter, an eighth, a sixteenth of a
# second apart: which codes a clip smallest depends on its motion)
FAST_DEPTH = -1  # the one depth of effort "fast", added to the clip's (knots an eighth of a second apart): on 30
# shared files (CMU and other BVH, ASF/AMC, C3D, TRC) at 1 cm it codes within 0.5 % of effort medium's search, the
# clip's own depth 1.2 % (CMU) to 19 % (others) larger
SAMPLE_S = 6.0  # a long clip's settings are chosen on two windows of this many seconds, then coded whole
Maker = Callable[[float], "tuple[float, np.ndarray | None]"]


class Base:
    """A base the correction may be added to: ``values`` ``(frames, columns)`` costing ``extra`` bytes of its own,
    or one made when it is first needed by ``make(cap) -> (extra, values)`` (a model's encoding and decoding),
    which may give up once its own bytes reach ``cap`` (values None, ``extra`` the bytes it reached: it cannot be
    the smaller file). Until made, ``extra`` is a lower bound of its own bytes."""

    def __init__(self, values: np.ndarray | None, extra: float, make: Maker | None = None) -> None:
        self.values, self.extra, self.make = values, extra, make

    def within(self, cap: float = math.inf) -> bool:
        """Whether its own bytes are under ``cap`` (made if it must be to tell)."""
        if self.values is None and self.extra < cap and self.make is not None:
            self.extra, self.values = self.make(cap)
        return self.values is not None and self.extra < cap


def search(clip: Clip, base: np.ndarray, target: Target, depth: int | None = None) -> Correction:
    """The smallest correction meeting ``target``: each setting of :data:`RELAXES` x :data:`DEPTHS` is tried
    with :func:`bound_search` (on two windows of a long clip: a prediction, then the chosen setting is coded
    and verified on the whole clip; should it miss, the first setting is). The first setting's bound starts
    the others' searches (a distortion or ARMS target's bound hardly depends on the setting), and the
    windows' bound the whole clip's. ``depth``: the lifting depth, when known (e.g. chosen on another base
    of the same clip)."""
    return search_bases(clip, [base], [0], target, depth)[1]


def search_bases(clip: Clip, bases: list[np.ndarray | Base], extra: list[int], target: Target,
                 depth: int | None = None, effort: str = "medium") -> tuple[int, Correction]:
    """The base (``(frames, columns)`` values the correction is added to, each costing ``extra`` bytes of its
    own; or a :class:`Base`, made only where it may be the smaller, its ``extra`` entry unused) and the correction
    coding the clip smallest, ``(index, correction)``. On a short clip every base is
    searched whole, the first one's settings as :func:`search` does, the others at the lifting depth it chose;
    on a long one the bases are compared on the two windows (their corrections' bytes scaled to the clip, plus
    their own; the depth searched on the base of the fewest bytes of its own, a base whose own bytes alone reach
    another's prediction left out: :func:`_predict`) and only the best is coded whole, verified, and searched on
    its own if it misses (then the other bases are searched whole as well). The smallest is returned, met or
    not: the caller says what missed.

    ``effort`` (the codec option): ``"fast"`` tries one lifting depth, :data:`FAST_DEPTH` (with a max error
    target each base is then one fit, coded whole from the cheapest as on a short clip, the windows left out;
    they start a distortion or ARMS target's search; should that depth's rounds run out,
    :attr:`.fit.Correction.settled`, the depth below is coded as well and the smaller kept); ``"best"`` codes
    every setting on the whole clip, whatever its length."""
    given = [b if isinstance(b, Base) else Base(b, e) for b, e in zip(bases, extra, strict=True)]
    if effort == "fast" and depth is None:
        depth = max(1, clip.levels + FAST_DEPTH)
        found = _search_bases(clip, given, target, depth, effort)
        if found[1].settled or depth <= 1:
            return found
        # its verification rounds ran out (levels far up): one depth less as well, the smaller met kept
        other = _search_bases(clip, given, target, depth - 1, effort)
        return min(found, other, key=lambda f: (not target.met(f[1].errors), given[f[0]].extra + f[1].size))
    return _search_bases(clip, given, target, depth, effort)


def _search_bases(clip: Clip, bases: list[Base], target: Target, depth: int | None,
                  effort: str) -> tuple[int, Correction]:
    """:func:`search_bases` at one effort and ``depth`` (None: searched)."""
    # a known depth and a max error target: a base is one fit, and its windows would only predict that fit's
    # bytes; each base is coded whole (a base whose own bytes reach a met coding's whole bytes not at all)
    one_fit = depth is not None and len(RELAXES) == 1 and target.max_distortion is None and target.max_arms is None
    parts = [(clip, slice(None))] if effort == "best" or one_fit else _windows(clip)
    if parts[0][0] is clip:
        return _whole_bases(clip, bases, target, depth)
    predicted = _predict(clip, parts, bases, target, depth)
    del parts  # the windows' clips are not kept beside the whole clip's coding (peak memory)
    best = int(np.argmin([p[0] for p in predicted]))
    _, start, setting = predicted[best]
    cor = bound_search(clip, _values(bases[best]), target, *setting, start=start)
    searched = _cheapest(bases)
    first = _settings(clip, depth if best == searched else predicted[searched][2][1])[0]
    if not target.met(cor.errors) and setting != first:
        del cor  # replaced: not kept beside its replacement
        cor = bound_search(clip, _values(bases[best]), target, *first, start=start)
    if target.met(cor.errors) or len(bases) == 1:
        return best, cor
    found = {i: cor if i == best else _search_whole(clip, _values(b), target, cor.depth)
             for i, b in enumerate(bases) if i == best or b.within()}
    return min(found.items(), key=lambda f: bases[f[0]].extra + f[1].size)  # the first of equals


def _values(base: Base) -> np.ndarray:
    assert base.values is not None  # made (Base.within) before it is fitted
    return base.values


def _predict(clip: Clip, parts: list[tuple[Clip, slice]], bases: list[Base],
             target: Target, depth: int | None) -> list[tuple[float, float, tuple[float, int]]]:
    """Per base, what the windows ``parts`` of a long clip predict: the clip's bytes (its correction's, scaled
    from the windows' to the clip, plus the base's own ``extra``), the bound to start the whole clip's search
    from and the ``(relax_by, depth)`` setting. The bases go from the cheapest of their own (the correction
    alone first, :func:`_cheapest`): its depth is searched (or ``depth``), the others use the one it chose, and
    a base whose own bytes are no fewer than a base's whole predicted bytes is not tried (it cannot be the
    smaller: a correction costs bytes; its prediction is infinite)."""
    share = clip.motion.n_frames / sum(c.motion.n_frames for c, _ in parts)
    settings = _settings(clip, depth)
    predicted: list[tuple[float, float, tuple[float, int]]] = [(math.inf, 0.0, settings[0])] * len(bases)
    for i in _order(bases):
        if not bases[i].within(min(p[0] for p in predicted)):
            continue
        # per window and setting (size, bound): the windows' corrections themselves are not kept
        per_part = [[(c.size, c.bound) for c in _each_setting(w, _values(bases[i])[a], target, settings)]
                    for w, a in parts]
        sizes = [sum(p[k][0] for p in per_part) for k in range(len(settings))]
        k = int(np.argmin(sizes))
        start = math.exp(float(np.mean([math.log(p[k][1]) for p in per_part])))
        predicted[i] = (bases[i].extra + share * sizes[k], start, settings[k])
        settings = _settings(clip, settings[k][1])  # the next bases: at the depth the cheapest one chose
    return predicted


def _order(bases: list[Base]) -> list[int]:
    """The order the bases are tried in: from the fewest bytes of their own, a base not made yet after the others
    (its bytes unknown; with the depth given the order does not change what is chosen, only what is made)."""
    return sorted(range(len(bases)), key=lambda i: (bases[i].values is None, bases[i].extra))


def _cheapest(bases: list[Base]) -> int:
    """The base of the fewest bytes of its own (the first of equals): the one whose depth is searched."""
    return min(range(len(bases)), key=lambda i: bases[i].extra)


def _settings(clip: Clip, depth: int | None) -> list[tuple[float, int]]:
    """The ``(relax_by, depth)`` settings tried: every depth of :data:`DEPTHS`, or the one given."""
    depths = [depth] if depth is not None else [max(1, clip.levels + d) for d in DEPTHS]
    return list(dict.fromkeys((r, dp) for dp in depths for r in RELAXES))


def _whole_bases(clip: Clip, bases: list[Base], target: Target, depth: int | None) -> tuple[int, Correction]:
    """A short clip's bases each searched whole, from the cheapest of their own bytes (the correction alone
    first, :func:`_cheapest`): its lifting depth searched (or ``depth``), the others at the one it chose; a base
    whose own bytes alone reach a met coding's whole bytes is not tried (it cannot be the smaller)."""
    found: dict[int, Correction] = {}
    for i in _order(bases):
        smallest = min((bases[j].extra + c.size for j, c in found.items() if target.met(c.errors)), default=math.inf)
        if not bases[i].within(smallest):
            continue
        found[i] = _search_whole(clip, _values(bases[i]), target,
                                 depth if not found else next(iter(found.values())).depth, smallest - bases[i].extra)
    return min(sorted(found.items()), key=lambda f: bases[f[0]].extra + f[1].size)  # the first of equals


def _search_whole(clip: Clip, base: np.ndarray, target: Target, depth: int | None,
                  give_up: float = math.inf) -> Correction:
    """Every setting coded on the whole clip; the smallest met (the first of equals), else the first (the
    others are not kept while the next is coded: peak memory). ``give_up``: bytes a correction is not worth
    having at (:func:`bound_search`)."""
    settings = _settings(clip, depth)
    first = bound_search(clip, base, target, *settings[0], give_up=give_up)
    best = first if target.met(first.errors) else None
    for r, dp in settings[1:]:
        cor = bound_search(clip, base, target, r, dp, start=first.bound, give_up=give_up)
        if target.met(cor.errors) and (best is None or cor.size < best.size):
            best = cor
        del cor
    return best if best is not None else first


def _each_setting(clip: Clip, base: np.ndarray, target: Target,
                  settings: list[tuple[float, int]]) -> list[Correction]:
    """:func:`bound_search` with each ``(relax_by, depth)`` setting, the first one's bound starting the others'."""
    first = bound_search(clip, base, target, *settings[0])
    return [first] + [bound_search(clip, base, target, r, dp, start=first.bound) for r, dp in settings[1:]]


def _windows(clip: Clip) -> list[tuple[Clip, slice]]:
    """``[(clip, every frame)]``, or for a long clip (over three windows of :data:`SAMPLE_S`; not a block, whose
    decisions are the whole clip's) two windows centred at a third and two thirds of it, each as
    ``(Clip, frames slice)``."""
    motion = clip.motion
    w = max(256, int(SAMPLE_S * motion.frame_rate))
    n = motion.n_frames
    if n <= 3 * w or clip.whole is not None:
        return [(clip, slice(None))]
    out = []
    for centre in (n // 3, 2 * n // 3):
        a = max(0, centre - w // 2)
        sub = motion.slice(a, a + w)
        sub = replace(sub, metadata={k: v for k, v in sub.metadata.items() if k != "block_of"})
        out.append((Clip(sub, clip.contacts is not None).of_job(clip.work), slice(a, a + w)))
    return out


def bound_search(clip: Clip, base: np.ndarray, target: Target, relax_by: float, depth: int,
                 start: float | None = None, give_up: float = math.inf) -> Correction:
    """The correction with the largest bound meeting ``target`` (the bound is at most ``max_error``; for a
    distortion or ARMS target, secant steps in log space inside the bracket of met and missed bounds, at most
    :data:`SEARCH_FITS` fits, from ``start`` when given: a bound found with other settings; where two met bounds
    show the figures flat, :func:`_flat`, straight to the largest bound allowed: the base alone meets the target,
    the bound only decides what the correction adds). ``give_up``: with a
    max error target alone, bytes the correction is not worth having at (another base's file is no larger):
    :func:`.fit.fit` stops after its first round where that round's integers reach them."""
    e_cap = target.max_error
    if target.max_distortion is None and target.max_arms is None:
        assert e_cap is not None
        return fit(clip, base, e_cap, relax_by, depth, give_up=give_up)
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
        # far looser bounds leave the model's points as they are and only hold the feet: not worth a long search
        e_cap = min(e_cap if e_cap is not None else math.inf, LOOSEST * guesses[0])
    if start is not None and start > 0:
        guesses = [start]
    e = min(guesses + ([e_cap] if e_cap is not None else []))
    best: Correction | None = None  # the largest bound met so far
    low_fail = math.inf  # the smallest bound missed so far
    cur = fit(clip, base, e, relax_by, depth, lazy=True)  # only the correction kept is packed
    met_before: tuple[float, float] | None = None  # the last met fit's (bound, score)
    for _ in range(SEARCH_FITS):
        score = target.score(cur.errors)
        flat = False
        if score <= 1:
            best = cur if best is None or cur.bound > best.bound else best
            flat = met_before is not None and _flat(met_before, (cur.bound, score))
            met_before = (cur.bound, score)
        else:
            low_fail = min(low_fail, cur.bound)
        # secant in log space (the figures grow about linearly with the bound), kept inside the bracket; where
        # they hardly grow with it (the model's own errors: FLAT), straight to the largest bound allowed
        nxt = cur.bound * float(np.clip(0.95 / max(score, 1e-9), 0.25, 4.0))
        if e_cap is not None:
            nxt = e_cap if flat else min(nxt, e_cap)
        lo = best.bound if best is not None else 0.0
        if not lo < nxt < low_fail:
            nxt = math.sqrt(lo * low_fail) if lo > 0 and math.isfinite(low_fail) else (
                lo * 2.0 if lo > 0 else low_fail / 2.0)
        if (best is not None and (nxt <= best.bound * 1.08 or (e_cap is not None and best.bound >= e_cap)))\
                or (math.isfinite(low_fail) and nxt >= low_fail / 1.08 and best is not None):
            break
        del cur  # let go before the next fit (unless it is the best so far)
        cur = fit(clip, base, nxt, relax_by, depth, lazy=True)
    return best if best is not None else cur


def _flat(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """Whether two met fits' ``(bound, score)`` show the target's figures hardly growing with the bound (by less
    than :data:`FLAT` of it, in log space): what is left of them is the base's own errors."""
    (b0, s0), (b1, s1) = sorted((a, b))
    if not (b1 > b0 > 0 and s0 > 0 and s1 > 0):
        return False
    return math.log(s1 / s0) < FLAT * math.log(b1 / b0)
