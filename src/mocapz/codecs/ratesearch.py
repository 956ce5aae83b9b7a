"""Rate control for codecs with one setting: the coarsest setting whose decoded result meets a target.

Used by the baselines (subsampling factor, number of components, error threshold): the candidates run from
the finest setting to the coarsest, the errors grow along the list, and a bisection finds the last one that
meets the :class:`~mocapz.codecs.target.Target`, every probe checked by really decoding it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from mocapz.codecs.target import ErrorMetric, Errors, Target
from mocapz.errors import TargetError
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion

Sections = dict[str, bytes]


def coarsest_meeting(motion: AnyMotion, target: Target, candidates: Sequence[Any], encode_at: Callable[[Any], Sections],
                     decode: Callable[[Sections, ClipHeader], AnyMotion], codec: str) -> Sections:
    """The sections of the coarsest candidate meeting ``target`` (candidates ordered finest first).

    Raises TargetError when even the finest candidate misses the target.
    """
    metric, header = ErrorMetric(motion), ClipHeader.of(motion)

    def probe(i: int) -> tuple[bool, Sections, Errors]:
        sections = encode_at(candidates[i])
        errors = metric.of_motion(decode(sections, header))
        return target.met(errors), sections, errors

    good, best, errors = probe(0)
    if not good:
        raise _missed(motion, target, errors, codec, "its finest setting")
    lo, hi = 0, len(candidates) - 1  # candidates[lo] meets the target
    while lo < hi:
        mid = (lo + hi + 1) // 2
        good, sections, _ = probe(mid)
        if good:
            lo, best = mid, sections
        else:
            hi = mid - 1
    return best


def check_target(motion: AnyMotion, target: Target, sections: Sections,
                 decode: Callable[[Sections, ClipHeader], AnyMotion], codec: str) -> Sections:
    """``sections`` if their decoded result meets ``target`` (settings the user fixed), else TargetError."""
    errors = ErrorMetric(motion).of_motion(decode(sections, ClipHeader.of(motion)))
    if not target.met(errors):
        raise _missed(motion, target, errors, codec, "the settings given")
    return sections


def _missed(motion: AnyMotion, target: Target, e: Errors, codec: str, what: str) -> TargetError:
    where = motion.metadata.get("path", motion.name)
    return TargetError(f"{where}: the {codec} codec cannot meet the target ({target.describe()}): {what} "
                       f"give distortion {e.distortion_pct:.4g} %, max error {e.max_error:.4g} and ARMS "
                       f"{e.arms:.4g} file units (the lossless codec gives the values back exactly)")
