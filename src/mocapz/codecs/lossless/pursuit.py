"""The predictor choice of :func:`~.predict.choose_predictors` for every column of a clip without gaps at once.

Each column's matching pursuit runs as in :func:`~.predict._pursuit`, step by step, but the steps of all
columns go together: the scores, the picks, the least-squares solves (numpy's LAPACK gufunc, called once per
step on the stack of every column's system: the same routine on the same numbers as one call per column),
the rounding of the coefficients, the exact residuals and their costs (exact sums) are batched, and so are the
next step's correlations (one einsum over the stack: each column's products summed as the single-column einsum
sums them), so the predictors and coefficients come out identical (tests/test_lossless_speed_equal.py).
"""

from __future__ import annotations

import numpy as np

from mocapz.codecs.lossless.predict import (
    _LSTSQ,
    COEF_LIMIT,
    COEF_SHIFT,
    MAX_PREDICTORS,
    PREDICTOR_BITS,
    WINDOW,
    _lstsq,
)


def choose_shared(shared: tuple[np.ndarray, np.ndarray, np.ndarray], order: list[int],
                  rows: int) -> list[tuple[list[int], np.ndarray]]:
    """``choose_predictors(d2, c, order[:k], every_row, shared)`` for each ``k, c`` of ``order``."""
    full, big = shared[1], shared[2]
    table: list[tuple[list[int], np.ndarray]] = [([], np.zeros(0, dtype=np.int64)) for _ in order]
    todo = [k for k in range(len(order)) if k > 0] if rows >= 8 else []
    if not todo or _LSTSQ is None:
        from mocapz.codecs.lossless.predict import choose_predictors

        every = np.arange(rows)
        return [choose_predictors(full.T, c, order[:k], every, shared) if k in todo else table[k]
                for k, c in enumerate(order)]
    cands = [order[:k][-WINDOW:] for k in todo]
    cols = np.asarray([order[k] for k in todo], dtype=np.int64)
    size = np.asarray([len(c) for c in cands], dtype=np.int64)
    n_col = len(todo)
    pad = np.zeros((n_col, WINDOW), dtype=np.int64)
    valid = np.arange(WINDOW)[None, :] < size[:, None]
    for i, cand in enumerate(cands):
        pad[i, : len(cand)] = cand
    rhs = big[pad, cols[:, None]]  # (columns, WINDOW)
    norms = np.sqrt(big[pad, pad]) + 1e-9
    corr = rhs.copy()
    steps = np.minimum(size, MAX_PREDICTORS)
    best_cost = _costs(full[cols])
    best_n = np.zeros(n_col, dtype=np.int64)  # each column's best prefix: its length, members and coefficients
    best_members = np.zeros((n_col, MAX_PREDICTORS), dtype=np.int64)
    best_coef = np.zeros((n_col, MAX_PREDICTORS), dtype=np.int64)
    chosen = np.zeros((n_col, MAX_PREDICTORS), dtype=np.int64)
    active = np.ones(n_col, dtype=bool)
    for step in range(MAX_PREDICTORS):
        active &= step < steps
        if not active.any():
            break
        score = np.abs(corr) / norms
        score[~valid] = -np.inf
        np.put_along_axis(score, chosen[:, :step], -1.0, axis=1)
        j = np.argmax(score, axis=1)
        active &= score[np.arange(n_col), j] > 1e-9
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        chosen[idx, step] = j[idx]
        n = step + 1
        pick = chosen[idx, :n]  # (a, n) positions in each column's candidates
        members = pad[idx[:, None], pick]  # (a, n) the picked columns
        sub = big[members[:, :, None], members[:, None, :]]  # (a, n, n)
        b = rhs[idx[:, None], pick]
        with np.errstate(all="ignore"):
            sol = _LSTSQ(sub, b[:, :, None], np.finfo(np.float64).eps * n, signature="ddd->ddid")[0][:, :, 0]
        coef = np.minimum(np.maximum(np.round(sol * (1 << COEF_SHIFT)), -COEF_LIMIT), COEF_LIMIT).astype(np.int64)
        weights = coef / float(1 << COEF_SHIFT)
        acc = full[members[:, 0]] * weights[:, :1]  # exact sums: any order gives these numbers
        for m in range(1, n):
            acc += full[members[:, m]] * weights[:, m : m + 1]
        resid = full[cols[idx]] - acc
        for a in np.flatnonzero(~np.isfinite(sol).all(axis=1)).tolist():  # the wrapper's own error or numbers
            sol[a] = _lstsq(np.ascontiguousarray(sub[a]), np.ascontiguousarray(b[a]))
            coef[a] = np.minimum(np.maximum(np.round(sol[a] * (1 << COEF_SHIFT)), -COEF_LIMIT), COEF_LIMIT)
            resid[a] = full[cols[idx[a]]] - np.einsum("ki,k->i", full[members[a]], coef[a] / float(1 << COEF_SHIFT),
                                                      optimize=False)
        more = step + 1 < steps[idx]  # the correlations of the next step (einsum per column, batched: the same sums)
        if more.any():
            gram_cols = big[pad[idx[more]][:, :, None], members[more][:, None, :]]  # (a, WINDOW, n)
            corr[idx[more]] = rhs[idx[more]] - np.einsum("ajk,ak->aj", gram_cols, sol[more], optimize=False)
        cost = _costs(resid) + PREDICTOR_BITS * n
        better = cost < best_cost[idx]
        won = idx[better]
        best_cost[won] = cost[better]
        best_n[won] = n
        best_members[won, :n] = members[better]
        best_coef[won, :n] = coef[better]
    best = [(best_members[i, : best_n[i]].tolist(), best_coef[i, : best_n[i]].copy()) for i in range(n_col)]
    for i, k in enumerate(todo):
        table[k] = best[i]
    return table


def _costs(r: np.ndarray) -> np.ndarray:
    """:func:`~.predict._cost` of every row of ``r`` ``(columns, rows)`` at once: the same numbers (the sums of
    absolute residuals are exact, and ``log2`` gives the same values on an array as on one number)."""
    if not r.shape[1]:
        return np.zeros(r.shape[0])
    mean = np.add.reduce(np.abs(r), axis=1) / np.float64(r.shape[1])
    return r.shape[1] * np.log2(mean + 1.0)
