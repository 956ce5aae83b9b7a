"""Prediction shared by the lossless encoder and decoder (exact integer arithmetic only).

Residual of column ``c`` at frame ``t >= 2``::

    d2[t, c] = x[t, c] - 2 x[t-1, c] + x[t-2, c]
    r[t, c]  = d2[t, c] - ((sum_k coef[c, k] * d2[t, p_k]) + 512) >> 10

where ``p_k`` are the (at most two) columns of the same group (joint, marker) coded before ``c``.
"""

from __future__ import annotations

import numpy as np

COEF_SHIFT = 10
MAX_PREDICTORS = 2


def predictor_columns(groups: list[list[int]]) -> list[tuple[int, list[int]]]:
    """Coding order: ``(column, predictor columns)`` for every column of every group."""
    order = []
    for cols in groups:
        for i, c in enumerate(cols):
            order.append((c, cols[max(0, i - MAX_PREDICTORS) : i]))
    return order


def cross_term(d2: np.ndarray, preds: list[int], coef: np.ndarray) -> np.ndarray:
    """Integer prediction of one column's second differences from its predictor columns."""
    if not preds:
        return np.zeros(d2.shape[0], dtype=np.int64)
    acc = d2[:, preds] @ coef.astype(np.int64)
    return (acc + (1 << (COEF_SHIFT - 1))) >> COEF_SHIFT


def fit_coef(d2: np.ndarray, col: int, preds: list[int]) -> np.ndarray:
    """Least-squares predictor coefficients, rounded to the fixed-point grid (kept only if they help)."""
    if not preds or d2.shape[0] < 4:
        return np.zeros(len(preds), dtype=np.int64)
    a = d2[:, preds].astype(np.float64)
    y = d2[:, col].astype(np.float64)
    sol, *_ = np.linalg.lstsq(a, y, rcond=None)
    coef = np.clip(np.round(sol * (1 << COEF_SHIFT)), -(1 << 20), 1 << 20).astype(np.int64)
    gain = np.abs(y).sum() - np.abs(y - cross_term(d2, preds, coef)).sum()
    return coef if gain > 0 else np.zeros(len(preds), dtype=np.int64)
