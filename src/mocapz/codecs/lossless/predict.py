"""Prediction shared by the lossless encoder and decoder (exact integer arithmetic only).

Columns are coded in a fixed order (skeleton channels, or marker x y z). Residual of column ``c`` at
frame ``t >= 2``::

    d2[t, c] = x[t, c] - 2 x[t-1, c] + x[t-2, c]
    r[t, c]  = d2[t, c] - ((sum_k coef[c, k] * d2[t, p_k]) + 512) >> 10

where the ``p_k`` are up to :data:`MAX_PREDICTORS` columns coded before ``c`` (any joint or marker among
the :data:`WINDOW` columns before it), chosen by the encoder (greedy matching pursuit on the second
differences, kept only while they pay for their coefficients) and listed in the ``coef`` section
(:func:`pack_predictors`).
"""

from __future__ import annotations

import numpy as np

from mocapz.codecs.lossless.coding import pack_small, unpack_small
from mocapz.errors import FormatError
from mocapz.format.entropy import read_uvarint, unzigzag, write_uvarint, zigzag

COEF_SHIFT = 8
COEF_LIMIT = 1 << 20
MAX_PREDICTORS = 6
WINDOW = 64  # candidate predictors: the columns coded just before
FIT_ROWS = 2048  # rows used to choose and fit predictors (evenly spread)
PREDICTOR_BITS = 24.0  # estimated cost of one predictor (its index and coefficient) in bits
PATIENCE = 2  # a column's own pursuit (no shared fit) stops after this many steps in a row not lowering its cost


def coding_order(groups: list[list[int]]) -> list[int]:
    """The columns in coding order (groups in order, columns of a group in order)."""
    return [c for g in groups for c in g]


def cross_term(d2: np.ndarray, preds: list[int], coef: np.ndarray) -> np.ndarray:
    """Integer prediction of one column's second differences from its predictor columns."""
    if not preds:
        return np.zeros(d2.shape[0], dtype=np.int64)
    acc = d2[:, preds] @ np.asarray(coef, dtype=np.int64)
    return (acc + (1 << (COEF_SHIFT - 1))) >> COEF_SHIFT


def _cost(r: np.ndarray) -> float:
    """Estimated bits of residuals ``r`` (Laplace: ``n * log2(mean |r| + 1)``; the mean as ``ndarray.mean``
    computes it, without its overhead)."""
    if not r.size:
        return 0.0
    mean = np.float64(np.add.reduce(np.abs(r))) / np.float64(r.size)
    return float(r.size * np.log2(mean + 1.0))


def _lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.linalg.lstsq(a, b, rcond=None)[0]`` for a small square ``a``: the same LAPACK call (gelsd) through
    numpy's gufunc, without the wrapper's overhead; the wrapper itself wherever that call is missing or fails."""
    if _LSTSQ is not None:
        with np.errstate(all="ignore"):
            x = _LSTSQ(a, b[:, None], np.finfo(np.float64).eps * a.shape[0], signature="ddd->ddid")[0][:, 0]
        if np.isfinite(x).all():
            return x
    return np.linalg.lstsq(a, b, rcond=None)[0]


try:
    from numpy.linalg import _umath_linalg

    _LSTSQ = _umath_linalg.lstsq
except (ImportError, AttributeError):  # pragma: no cover - another numpy layout
    _LSTSQ = None


def shared_fit(d2: np.ndarray, columns: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """For clips without gaps (every column fitted on the same rows): the fit rows, their float second
    differences (transposed: ``(columns, rows)``) and the Gram matrix of all ``columns`` at once, which gives every
    column's Gram block and right-hand side bit for bit as :func:`choose_predictors` would compute them, since
    every product and partial sum is then an integer below ``2**53`` (exact in any order); None where that
    does not hold."""
    frames = d2.shape[0]
    rows = np.arange(frames)
    if frames > FIT_ROWS:
        rows = rows[np.linspace(0, frames - 1, FIT_ROWS).astype(np.int64)]
    a = d2[rows].astype(np.float64)
    cols = np.asarray(columns, dtype=np.int64)
    if not cols.size or float(np.max(np.einsum("ij,ij->j", a[:, cols], a[:, cols], optimize=False))) >= 2.0**52:
        return None
    gram = np.zeros((d2.shape[1], d2.shape[1]))
    gram[np.ix_(cols, cols)] = np.einsum("ij,ik->jk", a[:, cols], a[:, cols], optimize=False)
    return rows, np.ascontiguousarray(a.T), gram


def choose_predictors(d2: np.ndarray, col: int, before: list[int], rows: np.ndarray,
                      shared: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> tuple[list[int], np.ndarray]:
    """Predictor columns and fixed-point coefficients for ``col``.

    Greedy matching pursuit on the normal equations: each step adds the candidate most correlated with the
    least-squares residual; the prefix with the lowest estimated cost (residual bits + :data:`PREDICTOR_BITS`
    per predictor) wins. Where the column has a fit of its own (``shared`` None: a clip with gaps, or with values
    too large for exact sums) the pursuit stops once :data:`PATIENCE` steps in a row have not lowered the best
    cost: each step is a fit of that column alone, and most columns of a marker or ASF/AMC clip gain nothing
    from their first predictor on.

    Args:
        d2: ``(frames - 2, columns)`` int64 second differences, final for the columns in ``before``.
        col: the column to predict.
        before: the columns coded before it (candidates: the last :data:`WINDOW`).
        rows: indices of the rows where ``col`` is observed (the fit uses at most :data:`FIT_ROWS` of them).
        shared: :func:`shared_fit` of ``d2`` when every row is observed (the same numbers, computed once).
    """
    cand = before[-WINDOW:]
    if not cand or rows.size < 8:
        return [], np.zeros(0, dtype=np.int64)
    if shared is not None:  # exact integers throughout: the same numbers from the shared arrays
        return _pursuit(shared[1][col], shared[1], cand, shared[2][np.ix_(cand, cand)], shared[2][cand, col])
    if rows.size > FIT_ROWS:
        rows = rows[np.linspace(0, rows.size - 1, FIT_ROWS).astype(np.int64)]
    y = d2[rows, col].astype(np.float64)
    a = d2[np.ix_(rows, cand)].astype(np.float64)
    # einsum, not BLAS: a multi-threaded BLAS spinning on a loaded machine is 20x slower here
    gram = np.einsum("ij,ik->jk", a, a, optimize=False)
    rhs = np.einsum("ij,i->j", a, y, optimize=False)
    return _pursuit(y, a, cand, gram, rhs, shared=False)


def _pursuit(y: np.ndarray, a: np.ndarray, cand: list[int], gram: np.ndarray, rhs: np.ndarray,
             shared: bool = True) -> tuple[list[int], np.ndarray]:
    """The matching pursuit of :func:`choose_predictors`; ``a``: the candidates' second differences, ``(rows,
    candidates)``, or (``shared``) every column's, transposed."""
    norms = np.sqrt(np.diag(gram)) + 1e-9
    best: tuple[float, list[int], np.ndarray] = (_cost(y), [], np.zeros(0, dtype=np.int64))
    chosen: list[int] = []
    corr = rhs.copy()
    steps = min(MAX_PREDICTORS, len(cand))
    idle = 0  # steps since the best cost last fell
    for step in range(steps):
        score = np.abs(corr) / norms
        score[chosen] = -1.0
        j = int(np.argmax(score))
        if score[j] <= 1e-9:
            break
        chosen.append(j)
        sol = _lstsq(gram[chosen][:, chosen], rhs[chosen])
        coef = np.minimum(np.maximum(np.round(sol * (1 << COEF_SHIFT)), -COEF_LIMIT), COEF_LIMIT).astype(np.int64)
        weights = coef / float(1 << COEF_SHIFT)
        if shared:  # exact sums: any order gives these numbers
            resid = y - np.einsum("ki,k->i", a[[cand[i] for i in chosen]], weights, optimize=False)
        else:
            resid = y - np.einsum("ik,k->i", a[:, chosen], weights, optimize=False)
        cost = _cost(resid) + PREDICTOR_BITS * len(chosen)
        idle = 0 if cost < best[0] else idle + 1
        if cost < best[0]:
            best = (cost, [cand[i] for i in chosen], coef)
        if idle >= PATIENCE and not shared:
            break
        if step + 1 < steps:  # the correlations of the next step
            corr = rhs - np.einsum("jk,k->j", gram[:, chosen], sol, optimize=False)
    return best[1], best[2]


def pack_predictors(order: list[int], table: list[tuple[list[int], np.ndarray]]) -> bytes:
    """The ``coef`` section: uvarint length and small list (:func:`~.coding.pack_small`) of, per column in
    coding order, the predictor count and each predictor's distance back in the coding order; then a small
    list of all the zig-zagged coefficients."""
    where = {c: i for i, c in enumerate(order)}
    meta: list[int] = []
    coefs: list[int] = []
    for i, (preds, coef) in enumerate(table):
        meta.append(len(preds))
        meta.extend(i - where[p] for p in preds)
        coefs.extend(int(v) for v in coef)
    head = pack_small(np.asarray(meta, dtype=np.uint64))
    return write_uvarint(len(head)) + head + pack_small(zigzag(np.asarray(coefs, dtype=np.int64)))


def unpack_predictors(order: list[int], data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`pack_predictors` (every count, distance and coefficient checked), as arrays over the
    columns in coding order: the predictor counts ``(n,)``, the predictor columns and their coefficients ``(n,
    MAX_PREDICTORS)`` (zero beyond each count)."""
    n = len(order)
    size, pos = read_uvarint(data, 0)
    if pos + size > len(data):
        raise FormatError(None, "corrupted lossless stream (predictor table)")
    meta_arr = unpack_small(data[pos : pos + size], at_most=(1 + MAX_PREDICTORS) * n)
    values = unzigzag(unpack_small(data[pos + size :], at_most=MAX_PREDICTORS * n))
    if values.size and int(np.abs(values).max()) > COEF_LIMIT:
        raise FormatError(None, "corrupted lossless stream (predictor coefficient)")
    if meta_arr.size and int(meta_arr.max()) > WINDOW:  # every count and distance is at most WINDOW
        raise FormatError(None, "corrupted lossless stream (predictor table)")
    meta = meta_arr.astype(np.int64)
    starts = np.empty(n, dtype=np.int64)  # where each column's count is (the one sequential step)
    listed, at = meta.tolist(), 0
    for i in range(n):
        if at >= len(listed) or listed[at] > MAX_PREDICTORS:
            raise FormatError(None, "corrupted lossless stream (predictor table)")
        starts[i] = at
        at += 1 + listed[at]
    npred = meta[starts] if n else np.zeros(0, dtype=np.int64)
    if at != meta.size or int(npred.sum()) != values.size:
        raise FormatError(None, "corrupted lossless stream (predictor table length)")
    slot = np.arange(MAX_PREDICTORS)
    used = slot[None, :] < npred[:, None]  # (n, MAX_PREDICTORS)
    back = np.where(used, meta[np.minimum(starts[:, None] + 1 + slot, max(meta.size - 1, 0))], 1)
    col = np.arange(n)[:, None]
    if np.any(used & ((back < 1) | (back > np.minimum(col, WINDOW)))):
        raise FormatError(None, "corrupted lossless stream (predictor table)")
    order_arr = np.asarray(order, dtype=np.int64)
    pidx = np.where(used, order_arr[np.maximum(col - back, 0)], 0)
    first = np.cumsum(npred) - npred
    pcoef = np.where(used, values[np.minimum(first[:, None] + slot, max(values.size - 1, 0))] if values.size else 0,
                     0)
    return npred, pidx, pcoef.astype(np.int64)
