"""Heading-aligned node coordinates (an extension of the paper, on by default; ``heading=False`` is the
paper as printed).

The paper stores a node's markers as offsets from the parent's reference marker in world axes, so the
same arm swing looks different after the performer turns. Here offsets are expressed in a frame that
turns with the body about the vertical axis: ``offset_local = Rz(-yaw) @ offset_world``. The yaw angle per
frame is measured on the markers that move most rigidly with the root marker (yaw-only Procrustes against
their mean layout), smoothed, and coded with the root trajectory, so both sides use the same decoded yaw.
"""

from __future__ import annotations

import numpy as np

from mocapz.codecs.patterns.gaussian import gaussian_smooth


def up_axis(positions: np.ndarray) -> int:
    """The vertical axis: largest median extent of the marker cloud per frame."""
    with np.errstate(invalid="ignore"):
        ext = np.nanmax(positions, axis=1) - np.nanmin(positions, axis=1)
        med = np.nanmedian(ext, axis=0)
    return int(np.argmax(np.nan_to_num(med)))


def _plane(up: int) -> tuple[int, int]:
    return {0: (1, 2), 1: (2, 0), 2: (0, 1)}[up]


def rigid_markers(filled: np.ndarray, observed: np.ndarray, root: int, count: int = 8) -> np.ndarray:
    """Indices of the markers whose distance to the root marker varies least (at most ``count``)."""
    d = np.linalg.norm(filled - filled[:, root : root + 1], axis=2)
    ok = observed & observed[:, root : root + 1]
    spread = np.array([np.std(d[ok[:, m], m]) if ok[:, m].sum() > 10 else np.inf for m in range(d.shape[1])])
    mean = np.array([np.mean(d[ok[:, m], m]) if ok[:, m].sum() > 10 else 0.0 for m in range(d.shape[1])])
    spread[root] = np.inf
    spread[mean < 1e-9] = np.inf
    order = np.argsort(spread / np.maximum(mean, 1e-9))
    return order[np.isfinite(spread[order])][:count]


def measure_yaw(filled: np.ndarray, observed: np.ndarray, root: int, up: int, sigma: float = 4.0) -> np.ndarray:
    """Smoothed yaw angle ``(T,)`` in radians of the body around the up axis."""
    t = filled.shape[0]
    sel = rigid_markers(filled, observed, root)
    if sel.size < 2 or t == 0:
        return np.zeros(t)
    a, b = _plane(up)
    rel = filled[:, sel] - filled[:, root : root + 1]
    w = (observed[:, sel] & observed[:, root : root + 1]).astype(np.float64)
    ref = (rel * w[..., None]).sum(axis=0) / np.maximum(w.sum(axis=0), 1)[:, None]
    x, y = rel[..., a], rel[..., b]
    rx, ry = ref[:, a], ref[:, b]
    s = (w * (rx * y - ry * x)).sum(axis=1)
    c = (w * (rx * x + ry * y)).sum(axis=1)
    yaw = np.unwrap(np.arctan2(s, c))
    return gaussian_smooth(yaw, sigma) if sigma > 0 else yaw


def rotate(vectors: np.ndarray, yaw: np.ndarray, up: int, inverse: bool = False) -> np.ndarray:
    """Rotate ``(T, m, 3)`` vectors by ``yaw`` ``(T,)`` about the up axis (``inverse``: by ``-yaw``)."""
    a, b = _plane(up)
    ang = -yaw if inverse else yaw
    c, s = np.cos(ang)[:, None], np.sin(ang)[:, None]
    out = vectors.copy()
    out[..., a] = c * vectors[..., a] - s * vectors[..., b]
    out[..., b] = s * vectors[..., a] + c * vectors[..., b]
    return out
