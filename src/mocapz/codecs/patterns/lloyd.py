"""The initial clustering of :mod:`.kmeans`: k-means++ seeds, then Lloyd iterations, step for step as scipy's
``scipy.cluster.vq.kmeans2(x, k, iter, minit="++", rng=Generator)`` takes them (the same random draws, the same
nearest-centre rule with ties to the first centre, the same means summed in the segments' order), in NumPy.

scipy's K-means is the reference (tests/test_patterns_lloyd.py: the same labels on the shared clips' segments and
on random data); importing ``scipy.cluster`` costs a process 0.26 s alone (it imports ``scipy.spatial`` and
``scipy.special``), 0.05-0.14 s of a skeletal clip's ``mocapz compress`` beside the rotations' ``scipy.spatial``.
Distances take scipy's formulas (under 5 features the squared differences summed feature by feature, from 5 ``-2
x.c + |x|^2 + |c|^2``, the product from BLAS) with NumPy's summation: they can differ from scipy's in the last bit,
which changes a label only where two centres lie at the same distance to the last bit (or a seed where the draw
falls on a boundary of the cumulative distances to the last bit).
"""

from __future__ import annotations

import numpy as np

SMALL_FEATURES = 5  # scipy's vq sums the squared differences directly below this many features


def kmeans_pp(x: np.ndarray, k: int, iterations: int, rng: np.random.Generator) -> np.ndarray:
    """Labels ``(N,)`` (int64, in ``0..k-1``) of ``k``-means on the rows of ``x`` ``(N, D)`` (float64): k-means++
    seeds drawn from ``rng``, then ``iterations`` Lloyd steps (an empty cluster keeps its centre); the labels
    are those of the last assignment, as scipy's ``kmeans2`` returns them."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    n, d = x.shape
    centres = np.empty((k, d))
    d2 = np.full(n, np.inf)  # squared distance of every row to its nearest seed so far
    for i in range(k):
        if i == 0:
            idx = int(rng.integers(n, high=None, size=None, dtype="int64", endpoint=False))
        else:
            np.minimum(d2, _squared_distances(x, centres[i - 1]), out=d2)
            with np.errstate(invalid="ignore", divide="ignore"):  # every row a seed already: as scipy's
                cum = (d2 / d2.sum()).cumsum()
            idx = int(np.searchsorted(cum, rng.uniform()))
        centres[i] = x[idx]
    labels = np.zeros(n, dtype=np.int64)
    for _ in range(iterations):
        labels = _nearest(x, centres)
        sums = np.zeros((k, d))
        for row, label in zip(x, labels.tolist(), strict=True):  # in the segments' order, as scipy's
            sums[label] += row  # update_cluster_means (a row at a time: np.add.at is 10x slower here)
        counts = np.bincount(labels, minlength=k)
        has = counts > 0
        sums[has] /= counts[has, None]
        sums[~has] = centres[~has]
        centres = sums
    return labels


def _squared_distances(x: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``(N,)`` squared distances of the rows to the point ``c`` ``(D,)`` (the seeds' nearest distances are the
    minimum over the seeds of these: the same numbers as over all seeds at once)."""
    diff = x - c
    return np.einsum("ij,ij->i", diff, diff)


def _nearest(x: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Index of the nearest centre of every row (the first of equals), by scipy's vq's arithmetic."""
    if x.shape[1] < SMALL_FEATURES:
        dist = np.zeros((x.shape[0], c.shape[0]))
        for f in range(x.shape[1]):
            diff = c[None, :, f] - x[:, f, None]
            dist += diff * diff
    else:
        dist = (-2.0 * (x @ c.T) + _row_squares(x)[:, None]) + _row_squares(c)[None, :]
    return np.argmin(dist, axis=1).astype(np.int64)


def _row_squares(a: np.ndarray) -> np.ndarray:
    """``sum_f a[:, f] ** 2`` ``(rows,)``."""
    return np.einsum("ij,ij->i", a, a)
