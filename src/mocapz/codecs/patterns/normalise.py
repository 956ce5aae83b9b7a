"""Time normalisation of segments (paper §III.B) and de-normalisation on decoding (§III.E).

Every segment of ``n`` frames is brought to the reference frame count ``L`` (the average segment length)
so that segments become vectors of one size. De-normalisation is linear interpolation from ``L`` back to
``n`` frames (matrix ``B_n``, ``n x L``). Normalisation is linear interpolation ``A_n`` when ``n <= L``,
corrected by the smallest change that makes ``B_n`` give the segment back exactly
(``A_n + B_n^T (B_n B_n^T)^-1 (I - B_n A_n)``); when a segment is shortened (``n > L``) it is combined with
linear smoothing, namely the least-squares fit ``pinv(B_n)``, the ``L``-frame pattern whose
de-normalisation is closest to the segment.
Segments are processed in groups of equal length, one matrix product per group.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np


@lru_cache(maxsize=4096)
def interp_matrix(n_out: int, n_in: int) -> np.ndarray:
    """``(n_out, n_in)`` linear interpolation from ``n_in`` evenly spaced samples to ``n_out``."""
    m = np.zeros((n_out, n_in))
    if n_in == 1:
        m[:, 0] = 1.0
        return m
    pos = np.linspace(0.0, n_in - 1.0, n_out) if n_out > 1 else np.zeros(1)
    lo = np.minimum(np.floor(pos).astype(np.int64), n_in - 2)
    frac = pos - lo
    rows = np.arange(n_out)
    m[rows, lo] = 1.0 - frac
    m[rows, lo + 1] += frac
    return m


@lru_cache(maxsize=4096)
def normalise_matrix(length: int, n: int) -> np.ndarray:
    """``(L, n)`` matrix taking an ``n``-frame segment to the reference length ``L``."""
    b = interp_matrix(n, length)
    if n <= length:
        a = interp_matrix(length, n)
        # linear interpolation, corrected (least change) so that de-normalising gives the segment back
        return a + b.T @ np.linalg.solve(b @ b.T, np.eye(n) - b @ a)
    return np.linalg.solve(b.T @ b, b.T)  # least squares: pinv of a full-column-rank B_n


def normalise(frames: np.ndarray, starts: np.ndarray, lengths: np.ndarray, length: int,
              observed: np.ndarray | None = None) -> np.ndarray:
    """Normalised segments ``(segments, L, D)`` from a sequence ``(T, D)`` and its segmentation.

    With ``observed`` ``(T, D)``, a shortened segment (``n > L``) with gaps is fitted to its observed
    samples only (weighted least squares, pulled lightly towards the plain fit where nothing is
    observed), so that a marker seen in a few frames only is still reproduced in those frames.
    """
    out = np.empty((len(starts), length, frames.shape[1]))
    for n in np.unique(lengths):
        sel = np.flatnonzero(lengths == n)
        idx = starts[sel][:, None] + np.arange(n)[None, :]
        out[sel] = np.einsum("ln,snd->sld", normalise_matrix(length, int(n)), frames[idx])
        if observed is None or n <= length:
            continue
        b = interp_matrix(int(n), length)
        for s_i, rows in zip(sel, idx, strict=True):
            obs = observed[rows]
            for c in np.flatnonzero(~obs.all(axis=0)):
                w = obs[:, c].astype(np.float64)
                lhs = b.T @ (w[:, None] * b) + RIDGE * np.eye(length)
                out[s_i, :, c] = np.linalg.solve(lhs, b.T @ (w * frames[rows, c]) + RIDGE * out[s_i, :, c])
    return out


RIDGE = 1e-3  # pull of the plain fit in the weighted normalisation of segments with gaps


def normalise_mask(observed: np.ndarray, starts: np.ndarray, lengths: np.ndarray, length: int) -> np.ndarray:
    """Observation flags ``(segments, L, D)`` of the normalised frames: 1 where an observed sample
    contributes to the normalised frame (its interpolation neighbours), else 0."""
    obs = observed.astype(np.float64)
    out = np.empty((len(starts), length, obs.shape[1]))
    for n in np.unique(lengths):
        sel = np.flatnonzero(lengths == n)
        idx = starts[sel][:, None] + np.arange(n)[None, :]
        m = interp_matrix(length, int(n)) if n <= length else interp_matrix(int(n), length).T
        out[sel] = np.einsum("ln,snd->sld", (np.abs(m) > 1e-12).astype(np.float64), obs[idx])
    return (out > 0).astype(np.float64)


def denormalise(patterns: np.ndarray, labels: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Concatenate patterns ``(K, L, D)`` picked by ``labels`` and stretched to ``lengths`` frames.

    Returns ``(sum(lengths), D)``.
    """
    total = int(lengths.sum())
    out = np.empty((total, patterns.shape[2]))
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    length = patterns.shape[1]
    for n in np.unique(lengths):
        sel = np.flatnonzero(lengths == n)
        seg = np.einsum("nl,sld->snd", interp_matrix(int(n), length), patterns[labels[sel]])
        idx = starts[sel][:, None] + np.arange(n)[None, :]
        out[idx] = seg
    return out
