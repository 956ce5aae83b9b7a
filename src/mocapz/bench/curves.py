"""Rate-distortion curves: Pareto fronts, the ratio a codec reaches at a given error level, corpus figures.

A codec's measured settings on a clip give points ``(error, ratio)``. Its curve is the Pareto front
(no other point has both a lower-or-equal error and a higher ratio). The ratio at an error level ``L``
is interpolated on the front between the two points around ``L``, linearly in ``log ratio`` against
``log error`` (against the error itself when the lower point has error 0); beyond the front's largest
error the best ratio measured is used (no extrapolation), and below its smallest error the level is
not reached (``None``). Over a corpus, the ratio at ``L`` is ``sum raw_bytes / sum (raw_bytes / ratio)``
over the clips that reach ``L`` (a size-weighted ratio, like compressing the clips together).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any


def pareto(points: Iterable[tuple[float, float]]) -> list[tuple[float, float]]:
    """Pareto front of ``(error, ratio)`` points, by increasing error (and increasing ratio)."""
    pts = sorted((float(e), float(r)) for e, r in points
                 if e is not None and r is not None and math.isfinite(e) and math.isfinite(r) and r > 0)
    front: list[tuple[float, float]] = []
    for e, r in sorted(pts, key=lambda p: (p[0], -p[1])):
        if not front or r > front[-1][1]:
            if front and front[-1][0] == e:
                continue
            front.append((e, r))
    return front


def ratio_at(points: Iterable[tuple[float, float]], level: float) -> float | None:
    """Ratio reached at error ``level`` on the curve of ``points`` (see the module docstring)."""
    front = pareto(points)
    below = [p for p in front if p[0] <= level]
    if not below:
        return None
    e0, r0 = below[-1]
    above = [p for p in front if p[0] > level]
    if not above:
        return r0
    e1, r1 = above[0]
    if e0 <= 0:
        t = level / e1
    else:
        t = math.log(level / e0) / math.log(e1 / e0)
    return math.exp(math.log(r0) + t * (math.log(r1) - math.log(r0)))


def metric_points(records: Sequence[dict[str, Any]], metric: str) -> list[tuple[float, float]]:
    """``(metric, ratio)`` of the successful records that have the metric."""
    return [(r[metric], r["ratio"]) for r in records
            if r.get("status") == "ok" and r.get(metric) is not None and r.get("ratio")]


def corpus_ratio(per_clip: Sequence[tuple[int, float | None]]) -> tuple[float | None, int]:
    """Size-weighted corpus ratio from ``(raw_bytes, ratio or None)`` per clip, and the clip count used."""
    used = [(raw, r) for raw, r in per_clip if r]
    if not used:
        return None, 0
    return sum(raw for raw, _ in used) / sum(raw / r for raw, r in used), len(used)
