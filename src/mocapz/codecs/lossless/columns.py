"""One representation per column (``REP_COLUMNS``), for text whose precision differs from column to column.

AMC files write six significant digits (``%g``): a column of values near 1 has six decimals, a column of
values near 100 four, and a column crossing zero has tiny values that no decimal count fits. Per column the
encoder picks, by estimated size, the decimal count (0-9) or the float forms (short decimal, float32,
float64); values a column's choice does not give back are exceptions as usual. The ``rep`` section then
holds ``REP_COLUMNS``, one representation byte per column, and one decimals byte per column.
"""

from __future__ import annotations

import numpy as np

from mocapz.codecs.lossless.integers import (
    REP_COLUMNS,
    REP_DECIMAL,
    REP_FLOAT32,
    REP_FLOAT64,
    REP_SHORT_DECIMAL,
    IntegerForm,
    integer_form,
    with_exceptions,
)
from mocapz.errors import FormatError

MAX_DECIMALS = 9
COLUMN_REPS = (REP_DECIMAL, REP_FLOAT32, REP_SHORT_DECIMAL, REP_FLOAT64)
HEADER_BITS = 16.0  # a column's representation and decimals bytes


def column_bits(form: IntegerForm) -> np.ndarray:
    """Estimated coded bits of each column of ``form`` (as :func:`~.integers.estimated_bits`, per column)."""
    x = form.ints
    if x.shape[0] > 2:
        d2 = np.abs(x[2:] - 2 * x[1:-1] + x[:-2]).astype(np.float64)
    else:
        d2 = np.abs(x).astype(np.float64)
    bits = np.log2(1.0 + d2).sum(axis=0)
    cols = x.shape[1]
    bits += 80.0 * np.bincount(form.exceptions % cols, minlength=cols)
    bits += 8.0 * np.bincount(form.negzero % cols, minlength=cols)
    return bits


def column_form(values: np.ndarray) -> tuple[IntegerForm, float]:
    """The per-column representation of finite ``(frames, columns)`` values and its estimated bits."""
    frames, cols = values.shape
    options: list[tuple[int, int, IntegerForm]] = []
    for d in range(MAX_DECIMALS + 1):
        options.append((REP_DECIMAL, d, integer_form(REP_DECIMAL, values, np.full(cols, d))))
    for rep in (REP_FLOAT32, REP_SHORT_DECIMAL, REP_FLOAT64):
        options.append((rep, 0, integer_form(rep, values)))
    bits = np.stack([column_bits(f) for _, _, f in options])  # (options, columns)
    pick = np.argmin(bits, axis=0)
    reps = np.array([options[k][0] for k in pick], dtype=np.int64)
    decs = np.array([options[k][1] for k in pick], dtype=np.int64)
    ints = np.empty((frames, cols), dtype=np.int64)
    for k in np.unique(pick).tolist():
        cols_k = np.flatnonzero(pick == k)
        ints[:, cols_k] = options[k][2].ints[:, cols_k]
    form = IntegerForm(REP_COLUMNS, ints, np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.int64),
                       columns=(reps, decs))
    total = float(bits[pick, np.arange(cols)].sum()) + HEADER_BITS * cols
    return with_exceptions(form, values), total


def pack_columns(form: IntegerForm) -> bytes:
    """The ``rep`` section of a per-column form: ``REP_COLUMNS``, the representation bytes, the decimals bytes."""
    assert form.columns is not None
    reps, decs = form.columns
    return bytes([REP_COLUMNS]) + reps.astype(np.uint8).tobytes() + decs.astype(np.uint8).tobytes()


def unpack_columns(data: bytes, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`pack_columns`: ``(columns,)`` representations and decimals, checked."""
    if len(data) != 1 + 2 * cols:
        raise FormatError(None, "corrupted lossless stream (column representations)")
    reps = np.frombuffer(data[1 : 1 + cols], dtype=np.uint8).astype(np.int64)
    decs = np.frombuffer(data[1 + cols :], dtype=np.uint8).astype(np.int64)
    if not np.isin(reps, COLUMN_REPS).all() or int(decs.max(initial=0)) > MAX_DECIMALS:
        raise FormatError(None, "corrupted lossless stream (column representations)")
    return reps, decs
