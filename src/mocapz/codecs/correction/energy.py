"""Added jitter: the acceleration energy decoded positions add to the original's, which the correction keeps
under :data:`JITTER` of the original's (:func:`jitter`; the samples to tighten where it is over).

Energy is the sum over frames and points of ``|second difference|^2`` of positions ``(frames, points, 3)`` (file
units squared). A block of a clip or a stream counts the second differences that end in it, the two across its
first edge included: they take in the last frames of the block before as coded (:func:`.context.edge`), as the
file's jitter does; its allowance is the clip's (:func:`.context.energy_reference`).
"""

from __future__ import annotations

import numpy as np

from mocapz.codecs.correction import context
from mocapz.model.motion import BlockOf

JITTER = 0.045  # added acceleration energy allowed (fraction of the original's), tightened beyond


def energies(whole: BlockOf | None, original: np.ndarray, valid: np.ndarray, pos: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """``(frames - 2, points)`` squared accelerations of the ``original`` positions (present samples ``valid``
    ``(frames, points)``) and of decoded positions ``pos``, 0 where a sample of the original is missing; a
    block's from the frames before it on (``(frames + edge - 2, points)``, the accelerations across its edge)."""
    edge = context.edge(whole)
    if edge is not None:
        pos, original, valid = (np.concatenate([e, x]) for e, x in zip(edge, (pos, original, valid), strict=True))
    ea, ok = context.acceleration_energy(original, valid)
    return ea, np.where(ok, context.squared_accelerations(pos), 0.0)


def _edge_frames(whole: BlockOf | None) -> int:
    edge = context.edge(whole)
    return 0 if edge is None else len(edge[0])


def jitter(whole: BlockOf | None, original: np.ndarray, valid: np.ndarray, pos: np.ndarray
           ) -> tuple[float, np.ndarray]:
    """The added acceleration energy of decoded positions ``pos`` (a fraction: of the original's, or for a block
    of what the clip's allowance leaves it) and ``(frames, points)`` True on the samples whose excess energy,
    largest first, makes up what is over :data:`JITTER` (to bring it to half of it)."""
    out = np.zeros(pos.shape[:2], dtype=bool)
    pre = _edge_frames(whole)
    if pos.shape[0] + pre < 3:
        return 0.0, out
    ea, eb = energies(whole, original, valid, pos)
    total = context.energy_reference(whole, float(ea.sum()), JITTER)
    if total <= 0:
        return 0.0, out
    jit = float(eb.sum()) / total - 1.0 if whole is None else (float(eb.sum()) - float(ea.sum())) / total
    if jit <= JITTER:
        return jit, out
    excess = (eb - ea).ravel()
    order = np.argsort(-excess)
    need = (jit - 0.5 * JITTER) * total  # bring it well under the limit
    n = int(np.searchsorted(np.cumsum(np.maximum(excess[order], 0.0)), need)) + 1
    hit = np.zeros(excess.size, dtype=bool)
    hit[order[:n]] = True
    hit = hit.reshape(eb.shape)
    # second difference k takes frames k, k + 1, k + 2 of the edge and the block: the block's k - pre to k - pre + 2
    frames = out.shape[0]
    for s in range(-pre, 3 - pre):
        k0, k1 = max(0, -s), min(hit.shape[0], frames - s)
        out[k0 + s:k1 + s] |= hit[k0:k1]
    return jit, out


def added(whole: BlockOf | None, original: np.ndarray, valid: np.ndarray, pos: np.ndarray) -> float:
    """Acceleration energy decoded positions ``pos`` add to the ``original``'s (0 without a clip around the
    block: nothing to account for)."""
    if whole is None or pos.shape[0] + _edge_frames(whole) < 3:
        return 0.0
    ea, eb = energies(whole, original, valid, pos)
    return float(eb.sum()) - float(ea.sum())
