"""The predictor choice of :func:`~.predict.choose_predictors` for every column of a clip without gaps at once.

Each column's matching pursuit runs as in :func:`~.predict._pursuit`, step by step, but the steps of all
columns go together: the scores, the picks, the least-squares solves (numpy's LAPACK gufunc, called once per
step on the stack of every column's system: the same routine on the same numbers as one call per column),
the rounding of the coefficients and the exact residuals are batched; what is neither exact nor elementwise
(the correlations' einsum, the cost's pairwise mean) is still computed column by column with the very calls
:func:`~.predict._pursuit` makes, so the predictors and coefficients come out identical.
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
    _cost,
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
    cand_rows = [np.asarray(cand, dtype=np.int64)[:, None] for cand in cands]
    rhs = big[pad, cols[:, None]]  # (columns, WINDOW)
    norms = np.sqrt(big[pad, pad]) + 1e-9
    corr = rhs.copy()
    steps = np.minimum(size, MAX_PREDICTORS)
    best_cost = [_cost(full[c]) for c in cols.tolist()]
    best: list[tuple[list[int], np.ndarray]] = [([], np.zeros(0, dtype=np.int64)) for _ in todo]
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
        finite = np.isfinite(sol).all(axis=1).tolist()
        for a, i in enumerate(idx.tolist()):
            if not finite[a]:  # the wrapper's own error or numbers
                sol_i = _lstsq(np.ascontiguousarray(sub[a]), np.ascontiguousarray(b[a]))
                coef_i = np.minimum(np.maximum(np.round(sol_i * (1 << COEF_SHIFT)), -COEF_LIMIT), COEF_LIMIT)
                coef[a] = coef_i.astype(np.int64)
                resid[a] = full[cols[i]] - np.einsum("ki,k->i", full[members[a]], coef[a] / float(1 << COEF_SHIFT),
                                                     optimize=False)
            else:
                sol_i = sol[a].copy()
            cand = cands[i]
            if step + 1 < steps[i]:
                gram_cols = big[cand_rows[i], members[a]]  # as big[np.ix_(cand, members)]
                corr[i, : len(cand)] = rhs[i, : len(cand)] - np.einsum("jk,k->j", gram_cols, sol_i, optimize=False)
            cost = _cost(resid[a]) + PREDICTOR_BITS * n
            if cost < best_cost[i]:
                best_cost[i] = cost
                best[i] = (members[a].tolist(), coef[a].copy())
    for i, k in enumerate(todo):
        table[k] = best[i]
    return table
