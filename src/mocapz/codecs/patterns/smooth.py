"""Smoothing across segment boundaries on decoding (paper §III.E).

Concatenated de-normalised patterns can jump where one segment ends and the next begins. At every
boundary the excess jump ``J = (x[b] - x[b-1]) - v`` is removed, where ``v`` is the expected step: the step
just before or just after the boundary, whichever is smaller, or 0 where they disagree in sign (the
"minmod" slope, which never mistakes a genuine jump inside a segment for the expected step). ``J`` is
spread by a cubic spline ramp over ``h`` frames on each side: the left side moves by ``+J/2 * s``, the
right side by ``-J/2 * s``, with ``s`` the cubic smoothstep rising from 0 at the window's outer edge to
almost 1 at the boundary. The result is C1-continuous where the segments were not, and untouched away
from boundaries. ``h`` is at most half of either segment, so a one-frame segment (a genuine jump, e.g.
an added T-pose frame) is never blended into its neighbours.
"""

from __future__ import annotations

import numpy as np


def _ramp(h: int) -> np.ndarray:
    """Cubic smoothstep weights ``(h,)`` for frames at distance 1..h from the boundary."""
    u = (h - np.arange(h) + 0.0) / (h + 1.0)
    return u * u * (3.0 - 2.0 * u)


def smooth_boundaries(frames: np.ndarray, lengths: np.ndarray, half_window: int,
                      observed: np.ndarray | None = None) -> np.ndarray:
    """Return ``frames`` ``(T, D)`` with the jumps at segment boundaries spread out.

    Args:
        frames: concatenated de-normalised segments, ``(T, D)``.
        lengths: ``(segments,)`` frame counts (sum ``T``).
        half_window: largest ``h`` (frames on each side of a boundary).
        observed: ``(T, members)`` observation flags, or None; boundaries where a member appears or
            disappears (the edge of a gap) are left alone, so real samples never blend with gap filling.
    """
    out = frames.copy()
    if half_window < 1 or len(lengths) < 2:
        return out
    starts = np.cumsum(lengths)[:-1]
    t = frames.shape[0]
    for k, b in enumerate(starts):
        b = int(b)
        if observed is not None and np.any(observed[b] != observed[b - 1]):
            continue
        h = int(min(half_window, lengths[k] // 2, lengths[k + 1] // 2))
        if h < 1:
            continue
        left = frames[b - 1] - frames[b - 2] if b >= 2 else np.zeros(frames.shape[1])
        right = frames[b + 1] - frames[b] if b + 1 < t else np.zeros(frames.shape[1])
        v = np.where(left * right > 0, np.where(np.abs(left) < np.abs(right), left, right), 0.0)
        jump = (frames[b] - frames[b - 1]) - v
        w = _ramp(h)[:, None] * (0.5 * jump)[None, :]
        out[b - 1 : b - 1 - h if b - 1 - h >= 0 else None : -1] += w
        out[b : b + h] -= w
    return out
