"""Adaptive K-means pattern extraction (paper §III.C).

Normalised segments are vectors ``x_j`` (``L`` frames x members x 3 values). Clustering starts with an
initial ``K`` (scipy's ``kmeans2``, :mod:`.lloyd`: k-means++ seeds, fixed seed) and grows ``K`` until the error
criterion holds: MaxError (eq. 2, every segment within ``tol`` of its cluster mean) or AveError (eq. 1, mean squared
error at most ``tol**2``). ``K`` grows without re-clustering from scratch: only the clusters that break the
bound are split in two (2-means inside the cluster), so the time stays near-linear in the data.

Errors are RMS member errors: ``err_j = sqrt(sum_d o_jd (x_jd - mu_d)**2 / (sum_d o_jd / c))`` where ``o``
are the observation weights (0 in gaps, which therefore never pull a mean or break a bound) and ``c`` the
values per member (3). The cluster means form the node's pattern database.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapz.codecs.patterns.lloyd import kmeans_pp

MAX = "max"
AVE = "ave"
ITERATIONS = 30  # Lloyd iterations of the initial clustering


@dataclass
class Clustering:
    """Result: ``centers`` ``(K, D)``, ``labels`` ``(N,)`` and the per-segment errors ``(N,)``."""

    centers: np.ndarray
    labels: np.ndarray
    errors: np.ndarray


def masked_means(x: np.ndarray, o: np.ndarray, labels: np.ndarray, k: int, ox: np.ndarray | None = None) -> np.ndarray:
    """Per-cluster weighted means ``(k, D)``; dimensions never observed take the plain mean. ``ox``: ``o * x``,
    when the caller has it (the same numbers)."""
    if k * len(labels) <= 4_000_000:
        onehot = np.zeros((k, len(labels)))
        onehot[labels, np.arange(len(labels))] = 1.0
        num, den = onehot @ (o * x if ox is None else ox), onehot @ o
        if (den > 1e-12).all():  # every dimension observed in every cluster: the weighted means alone
            return num / den
        plain, cnt = onehot @ x, onehot.sum(axis=1)[:, None]
    else:
        order = np.argsort(labels, kind="stable")
        lab = labels[order]
        starts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
        num, den, plain = (np.zeros((k, x.shape[1])) for _ in range(3))
        ids = lab[starts]
        num[ids] = np.add.reduceat((o * x)[order], starts, axis=0)
        den[ids] = np.add.reduceat(o[order], starts, axis=0)
        plain[ids] = np.add.reduceat(x[order], starts, axis=0)
        cnt = np.bincount(labels, minlength=k).astype(np.float64)[:, None]
    return np.where(den > 1e-12, num / np.maximum(den, 1e-12), plain / np.maximum(cnt, 1.0))


def sample_errors(x: np.ndarray, o: np.ndarray, centers: np.ndarray, per_member: int) -> np.ndarray:
    """RMS member error of each row of ``x`` against the row of ``centers`` beside it."""
    cnt = np.maximum(o.sum(axis=1) / per_member, 1e-12)
    return np.sqrt((o * (x - centers) ** 2).sum(axis=1) / cnt)


def _sq_dist(x: np.ndarray, o: np.ndarray, centers: np.ndarray,
             weighted: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Masked squared distances ``(N, K)``: ``sum_d o (x - c)**2``. ``weighted``: ``o * x`` and ``(o * x * x).sum(
    axis=1)``, when the caller has them (the same numbers)."""
    ox, sq = weighted if weighted is not None else _weighted(x, o)
    return np.maximum(sq[:, None] - 2.0 * ox @ centers.T + o @ (centers * centers).T, 0.0)


def _weighted(x: np.ndarray, o: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``o * x`` and ``(o * x * x).sum(axis=1)`` of :func:`_sq_dist`."""
    ox = o * x
    return ox, (ox * x).sum(axis=1)


def _bisect(x: np.ndarray, o: np.ndarray, iters: int = 8) -> np.ndarray:
    """Split rows into two groups by 2-means (masked); returns a boolean side per row."""
    weighted = _weighted(x, o)
    mean = masked_means(x, o, np.zeros(len(x), dtype=np.int64), 1, weighted[0])
    a = int(np.argmax(_sq_dist(x, o, mean, weighted)[:, 0]))
    b = int(np.argmax(_sq_dist(x, o, x[a : a + 1], weighted)[:, 0]))
    centers = np.stack([x[a], x[b]])
    side = np.zeros(len(x), dtype=bool)
    for _ in range(iters):
        d = _sq_dist(x, o, centers, weighted)
        new = d[:, 1] < d[:, 0]
        if new.all() or not new.any():
            new = np.zeros(len(x), dtype=bool)
            new[a] = True
        if np.array_equal(new, side):
            break
        side = new
        centers = masked_means(x, o, side.astype(np.int64), 2, weighted[0])
    return side


def adaptive_kmeans(x: np.ndarray, o: np.ndarray, tol: float, k0: int = 10, metric: str = MAX,
                    per_member: int = 3, seed: int = 0) -> Clustering:
    """Cluster normalised segments until the error bound holds.

    Args:
        x: ``(N, D)`` segment vectors (gaps filled with any finite value).
        o: ``(N, D)`` observation weights in [0, 1].
        tol: the bound, RMS member error in the units of ``x``.
        k0: initial number of clusters.
        metric: ``"max"`` (eq. 2) or ``"ave"`` (eq. 1).
        per_member: values per member (3: x, y, z).
        seed: random seed of the initial clustering.
    """
    n = x.shape[0]
    if n == 0:
        return Clustering(np.zeros((0, x.shape[1])), np.zeros(0, dtype=np.int64), np.zeros(0))
    labels = _initial(_impute(x, o), min(k0, n), seed)
    k = int(labels.max()) + 1
    centers = masked_means(x, o, labels, k)
    err = sample_errors(x, o, centers[labels], per_member)
    centers, labels, err = _grow(x, o, centers, labels, err, tol, metric, per_member)
    centers, labels, err = _refine(x, o, centers, labels, err, tol, metric, per_member)
    return Clustering(centers, labels, err)


def _impute(x: np.ndarray, o: np.ndarray) -> np.ndarray:
    """Values with unobserved entries replaced by their column's observed mean (for the initial K-means)."""
    obs = o > 0
    if obs.all():
        return x
    cnt = obs.sum(axis=0)
    mean = np.where(cnt > 0, np.where(obs, x, 0.0).sum(axis=0) / np.maximum(cnt, 1), 0.0)
    return np.where(obs, x, mean[None, :])


def _initial(x: np.ndarray, k: int, seed: int) -> np.ndarray:
    """Labels of an initial ``k``-means clustering (:func:`.lloyd.kmeans_pp`: scipy's ``kmeans2``, k-means++ seeds
    from ``seed``)."""
    if k <= 1:
        return np.zeros(len(x), dtype=np.int64)
    lab = kmeans_pp(x, k, ITERATIONS, np.random.default_rng(seed))
    _, lab = np.unique(lab, return_inverse=True)
    return lab.astype(np.int64)


def _grow(x, o, centers, labels, err, tol, metric, per_member):
    """Split offending clusters until the bound holds (MaxError) or the mean error does (AveError)."""
    centers = list(centers)
    members = [np.flatnonzero(labels == c) for c in range(len(centers))]  # each cluster's rows, increasing
    work = list(range(len(centers)))
    ave = metric != MAX  # the clusters' squared errors and their total: AveError's only
    sse = [float((err[m] ** 2).sum()) for m in members] if ave else []
    total = float((err**2).sum()) if ave else 0.0
    while True:
        if metric == MAX:
            if not work:
                break
            c = work.pop()
            if len(members[c]) < 2 or err[members[c]].max() <= tol:
                continue
        else:
            if total <= tol * tol * len(labels):
                break
            c = int(np.argmax(sse))
            if len(members[c]) < 2:
                break
        idx = members[c]
        side = _bisect(x[idx], o[idx])
        new = len(centers)
        for target, rows in ((c, idx[~side]), (new, idx[side])):
            mu = masked_means(x[rows], o[rows], np.zeros(len(rows), dtype=np.int64), 1)[0]
            err[rows] = sample_errors(x[rows], o[rows], mu[None], per_member)
            labels[rows] = target
            if target == new:
                centers.append(mu)
                members.append(rows)
            else:
                centers[c] = mu
                members[c] = rows
            if ave:
                sse[target:target + 1] = [float((err[rows] ** 2).sum())]  # the new cluster's appended
        if ave:
            total = float(sum(sse))
        work.extend([c, new])
    return np.asarray(centers), labels, err


def _refine(x, o, centers, labels, err, tol, metric, per_member, rounds: int = 3, budget: float = 5e8):
    """Reassign segments to their nearest pattern and re-average, as long as the bound still holds.

    Skipped when ``N * K * D`` exceeds ``budget`` (large libraries), which keeps the time near-linear.
    """
    n, k = len(labels), len(centers)
    if n * k * x.shape[1] > budget:
        return centers, labels, err
    for _ in range(rounds):
        cnt = np.maximum(o.sum(axis=1) / per_member, 1e-12)
        near = np.argmin(_sq_dist(x, o, centers), axis=1)
        used, near = np.unique(near, return_inverse=True)
        new_centers = masked_means(x, o, near, len(used))
        new_err = np.sqrt(np.maximum(_sq_dist(x, o, new_centers)[np.arange(n), near], 0.0) / cnt)
        ok = new_err.max() <= tol if metric == MAX else (new_err**2).mean() <= tol * tol
        if not ok or (new_err**2).sum() >= (err**2).sum() * (1 - 1e-6):
            break
        centers, labels, err = new_centers, near.astype(np.int64), new_err
    return centers, labels, err
