"""Global distortion control: search the clustering threshold and the quantisation bits for a target.

The target is a maximum ARMS and/or a maximum ``distortion_pct`` (METRICS.md). For a given number of bits
the clustering threshold ``tol`` is searched in log space (power-law secant steps inside a bracket); the
bits are then moved one at a time while that lowers the size. Every candidate is measured on the
encoder's own reconstruction (identical to the decoder's); the chosen one is checked by decoding its
bytes, and a :class:`~mocapz.errors.TargetError` is raised if no setting meets the target.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from mocapz.codecs.patterns.pipeline import Settings
from mocapz.codecs.target import ErrorMetric, Target
from mocapz.errors import TargetError
from mocapz.model.motion import AnyMotion, MarkerMotion

TOL_RANGE = (0.002, 0.4)  # searched clustering thresholds, fractions of the ADDH
BITS_RANGE = (2, 10)
MAX_STEPS = 6


def as_motion(motion: AnyMotion, values: np.ndarray) -> AnyMotion:
    return motion.with_positions(values) if isinstance(motion, MarkerMotion) else motion.with_channels(values)


MARGIN = 0.002  # searched settings keep 0.2 % below the target (float32 files, rounding)


@dataclass
class Trial:
    settings: Settings
    score: float
    size: int
    payload: Any


Runner = Callable[[Settings], tuple[list[np.ndarray], Any, int]]


def search(name: str, motions: list[AnyMotion], base: Settings, targets: list[Target], fixed: set[str],
           addh: float, run: Runner, check: Callable[[Any], float]) -> Any:
    """Smallest payload meeting every clip's target.

    Args:
        name: what to call the data in errors.
        motions: the original clips.
        base: settings the user gave (``fixed`` names those not to search: ``tolerance``, ``bits``).
        targets: per clip the target, in that clip's file units.
        addh: the length scale (for the first guess of the bits).
        run: ``settings -> (reconstruction per clip, payload, size in bytes)``.
        check: ``payload -> score`` measured by really decoding the payload.
    """
    cache: dict[tuple[int, float], Trial] = {}
    metrics = [ErrorMetric(m) for m in motions]

    def trial(bits: int, tol: float) -> Trial:
        key = (bits, round(tol, 6))
        if key not in cache:
            s = replace(base, bits=bits, tol=tol)
            decoded, payload, size = run(s)
            score = max((t.score(em.of_motion(as_motion(m, d)))
                         for t, em, m, d in zip(targets, metrics, motions, decoded, strict=True)), default=0.0)
            cache[key] = Trial(s, score / (1.0 - MARGIN), size, payload)
        return cache[key]

    def best_for(bits: int, guess: float) -> Trial | None:
        if "tolerance" in fixed:
            t = trial(bits, base.tol)
            return t if t.score <= 1 else None
        return _solve_tol(lambda tol: trial(bits, tol), guess)

    bits0 = base.bits if "bits" in fixed else _initial_bits(targets[0], addh)
    guess = base.tol if "tolerance" in fixed else 0.05
    best = best_for(bits0, guess)
    if "bits" not in fixed:
        bits = bits0
        while best is None and bits < BITS_RANGE[1]:
            bits += 1
            best = best_for(bits, guess)
        for direction in (-1, 1):
            b = best.settings.bits if best else bits0
            while best is not None and BITS_RANGE[0] <= b + direction <= BITS_RANGE[1]:
                cand = best_for(b + direction, best.settings.tol)
                if cand is None or cand.size >= best.size:
                    break
                best, b = cand, b + direction
    wanted = "; ".join(dict.fromkeys(t.describe() for t in targets))
    if best is None:
        raise TargetError(f"{name}: the patterns codec cannot meet the target ({wanted}) with these options")
    measured = check(best.payload)
    if measured > 1.0:
        raise TargetError(f"{name}: decoded result misses the target ({wanted}; "
                          f"measured {measured:.4f} of the allowed)")
    return best.payload


def _initial_bits(target: Target, addh: float) -> int:
    """Coarser quantisation for looser targets (ARMS relative to the ADDH)."""
    if target.max_arms is None:
        return 3
    rel = target.max_arms / max(addh, 1e-12)
    return 2 if rel > 0.03 else 3 if rel > 0.012 else 4 if rel > 0.006 else 5


def _solve_tol(trial: Callable[[float], Trial], guess: float) -> Trial | None:
    """Largest-passing / smallest-size search over the clustering threshold (log space)."""
    lo_t, hi_t = TOL_RANGE
    tol = min(max(guess, lo_t), hi_t)
    passing: list[Trial] = []
    failing: list[Trial] = []
    for _ in range(MAX_STEPS):
        t = trial(tol)
        (passing if t.score <= 1 else failing).append(t)
        best_pass = max(passing, key=lambda x: x.settings.tol, default=None)
        above = [f for f in failing if best_pass is None or f.settings.tol > best_pass.settings.tol]
        first_fail = min(above, key=lambda x: x.settings.tol, default=None)
        if best_pass is not None and first_fail is not None:
            a, b = best_pass.settings.tol, first_fail.settings.tol
            if b / a < 1.1:
                break
            tol = _secant(best_pass, first_fail)
        elif best_pass is not None:
            if best_pass.settings.tol >= hi_t:
                break
            tol = min(hi_t, best_pass.settings.tol * _grow(best_pass.score))
        else:
            if first_fail.settings.tol <= lo_t:
                break
            tol = max(lo_t, first_fail.settings.tol / _grow(1.0 / first_fail.score))
    return min(passing, key=lambda x: x.size, default=None)


def _grow(score: float) -> float:
    """Step factor towards the boundary from a score (power law ``score ~ tol``), clamped."""
    if score <= 0 or not math.isfinite(score):
        return 2.5
    return float(min(2.5, max(1.15, (1.0 / score) ** 1.0 * 1.02)))


def _secant(p: Trial, f: Trial) -> float:
    """Geometric interpolation of the threshold where the score crosses 1, kept inside the bracket."""
    a, b = math.log(p.settings.tol), math.log(f.settings.tol)
    sa, sb = math.log(max(p.score, 1e-9)), math.log(max(f.score, 1e-9))
    x = a + (0.0 - sa) * (b - a) / (sb - sa) if sb != sa else 0.5 * (a + b)
    x = min(max(x, a + 0.15 * (b - a)), b - 0.15 * (b - a))
    return math.exp(x)
