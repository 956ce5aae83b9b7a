"""Exact float <-> integer representations used by the lossless codec, with per-value exceptions.

A clip's ``(frames, columns)`` float64 values become int64 in one representation, chosen per clip:

* ``decimal``: ``round(value * 10**d)`` with the column's common decimals ``d`` (text formats);
* ``quantum``: ``round(value / q)`` for values stored as integers times a scale ``q`` (integer C3D);
* ``float32``: the float32 bit pattern mapped to an order-preserving integer (float C3D);
* ``float32 at decimals``: the same float32 integers for text that prints float32 values with ``d``
  decimals (``%.5f`` of a float32: TRC exports); the decoder rounds the float32 back to ``d`` decimals;
* ``short decimal``: the float32 integers for text written with few significant digits (``%g``: AMC);
  the decoder turns each float32 into its shortest decimal and reads that as float64;
* ``float32 quantum``: ``round(value / q)`` for float32 values that are multiples of a scale ``q`` rounded to
  float32 (float C3D written from integers: ``float32(i * q)``); ``q`` is found in the data;
* ``float64``: the float64 bit patterns (anything else).

Whatever the representation, a value it does not give back bit for bit is an **exception**: its
integer is a nearby placeholder (so prediction stays smooth) and its exact float64 bits travel apart
(:class:`Exceptions`). A ``-0`` that the integers give back as ``+0`` is kept in a sign list. So one odd
value (a float artefact, an extra decimal) costs a few bytes, never the whole clip's representation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

REP_DECIMAL, REP_FLOAT32, REP_FLOAT64, REP_SHORT_DECIMAL, REP_QUANTUM, REP_F32_DECIMAL, REP_F32_QUANTUM = range(7)
REP_COLUMNS = 7  # one representation per column (:mod:`.columns`)
REPRESENTATIONS = tuple(range(8))
QUANTUM_REPS = (REP_QUANTUM, REP_F32_QUANTUM)
_POW10 = 10.0 ** np.arange(-22, 23)  # exact doubles for |e| <= 22
_SIGN = np.int64(-0x8000000000000000)
_INT_LIMIT = 2.0**62  # placeholders stay far from int64 overflow in the second differences


@dataclass
class IntegerForm:
    """A clip's values as integers.

    Attributes:
        rep: the representation (``REP_*``).
        ints: ``(frames, columns)`` int64; placeholders where a value is an exception.
        exceptions: flat (row-major) indices of the values the integers do not give back, sorted.
        exact: ``(len(exceptions),)`` float64, those values.
        negzero: flat indices of the ``-0`` values the integers give back as ``+0``, sorted.
        quantum: the scale of ``REP_QUANTUM`` and ``REP_F32_QUANTUM`` (file units per integer step), else 0.
        columns: for ``REP_COLUMNS``, each column's representation and decimals ``(columns,)`` int64 each.
    """

    rep: int
    ints: np.ndarray
    exceptions: np.ndarray
    exact: np.ndarray
    negzero: np.ndarray
    quantum: float = 0.0
    columns: tuple[np.ndarray, np.ndarray] | None = None


def shortest_decimal(f32: np.ndarray) -> np.ndarray:
    """float64 of the shortest decimal (1-9 significant digits) that rounds to each float32 value.

    Pure IEEE arithmetic (exact powers of ten, correctly rounded multiply/divide/round), so encoder and
    decoder agree bit for bit; values it cannot handle (|exponent| > 22 after scaling) come back NaN.
    """
    v = f32.astype(np.float64)
    out = np.full(v.shape, np.nan)
    out[v == 0] = v[v == 0]
    a = np.abs(v)
    ok = (a > 0) & np.isfinite(a)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        e = np.floor(np.log10(np.where(ok, a, 1.0))).astype(np.int64)
        e = np.clip(e, -40, 40)
        # correct a log10 that is one off near powers of ten
        p = _pow10(e)
        e = np.where(ok & (p > a), e - 1, e)
        e = np.where(ok & (_pow10(e + 1) <= a), e + 1, e)
        todo = ok.copy()
        for k in range(1, 10):
            digits = k - 1 - e  # decimals giving k significant digits
            good = todo & (np.abs(digits) <= 22)
            scale = _pow10(np.where(good, digits, 0))
            cand = np.where(digits >= 0, np.round(v * scale) / scale, np.round(v / _pow10(-digits)) * _pow10(-digits))
            hit = good & (cand.astype(np.float32) == f32)
            out[hit] = cand[hit]
            todo &= ~hit
    return out


def _pow10(e: np.ndarray) -> np.ndarray:
    return _POW10[np.clip(e, -22, 22) + 22]


def _f32_ints(values: np.ndarray) -> np.ndarray:
    """Order-preserving int64 of each value's float32 (``+0 -> 0``, ``-0 -> -1``)."""
    with np.errstate(over="ignore", invalid="ignore"):
        bits = values.astype(np.float32).view(np.uint32).astype(np.int64)
    return np.where(bits >= (1 << 31), -(bits - (1 << 31)) - 1, bits)


def _f32_of(ints: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_f32_ints` (integers out of range wrap, which only damaged input produces)."""
    neg = ints < 0
    bits = np.where(neg, (-(ints + 1)) + (1 << 31), ints) & 0xFFFFFFFF
    return bits.astype(np.uint32).view(np.float32)


def _round_ints(scaled: np.ndarray) -> np.ndarray:
    """``round(scaled)`` as int64; non-finite or huge values get 0 (they are exceptions anyway)."""
    ok = np.isfinite(scaled) & (np.abs(scaled) < _INT_LIMIT)
    return np.where(ok, np.round(np.where(ok, scaled, 0.0)), 0.0).astype(np.int64)


def _column_scale(decimals: np.ndarray | None, cols: int) -> np.ndarray:
    if decimals is None:
        raise ValueError("this representation needs the column decimals")
    return 10.0 ** np.broadcast_to(np.asarray(decimals, dtype=np.float64), (cols,))


def to_ints(rep: int, values: np.ndarray, decimals: np.ndarray | None = None, quantum: float = 0.0) -> np.ndarray:
    """The ``(frames, columns)`` integers of finite ``values`` in representation ``rep`` (placeholders where a
    value does not fit: the nearest integer of the representation)."""
    with np.errstate(all="ignore"):  # huge values overflow to placeholders (they are exceptions): no warnings
        return _to_ints(rep, values, decimals, quantum)


def _to_ints(rep: int, values: np.ndarray, decimals: np.ndarray | None, quantum: float) -> np.ndarray:
    cols = values.shape[1] if values.ndim == 2 else 1
    if rep == REP_DECIMAL:
        return _round_ints(values * _column_scale(decimals, cols))
    if rep in QUANTUM_REPS:
        return _round_ints(values / quantum)
    if rep in (REP_FLOAT32, REP_SHORT_DECIMAL, REP_F32_DECIMAL):
        return _f32_ints(values)
    bits64 = values.view(np.int64)
    return np.where(bits64 < 0, -(bits64 & 0x7FFFFFFFFFFFFFFF) - 1, bits64)


def from_ints(rep: int, ints: np.ndarray, decimals: np.ndarray | None = None, quantum: float = 0.0) -> np.ndarray:
    """float64 values of ``ints`` in representation ``rep`` (exceptions and signs not applied)."""
    with np.errstate(all="ignore"):  # damaged or placeholder integers may give NaN or inf: no warnings
        return _from_ints(rep, np.asarray(ints, dtype=np.int64), decimals, quantum)


def _from_ints(rep: int, ints: np.ndarray, decimals: np.ndarray | None, quantum: float) -> np.ndarray:
    cols = ints.shape[1] if ints.ndim == 2 else 1
    if rep == REP_DECIMAL:
        return ints / _column_scale(decimals, cols)
    if rep == REP_QUANTUM:
        return ints.astype(np.float64) * np.float64(quantum)
    if rep == REP_F32_QUANTUM:
        return (ints.astype(np.float64) * np.float64(quantum)).astype(np.float32).astype(np.float64)
    if rep == REP_FLOAT32:
        return _f32_of(ints).astype(np.float64)
    if rep == REP_SHORT_DECIMAL:
        return shortest_decimal(_f32_of(ints))
    if rep == REP_F32_DECIMAL:
        scale = _column_scale(decimals, cols)
        return np.round(_f32_of(ints).astype(np.float64) * scale) / scale
    if rep != REP_FLOAT64:
        raise ValueError(f"unknown representation {rep}")
    neg = ints < 0
    mag = np.where(neg, -(ints + 1), ints)
    return np.where(neg, mag | _SIGN, mag).astype(np.int64).view(np.float64)


def integer_form(rep: int, values: np.ndarray, decimals: np.ndarray | None = None,
                 quantum: float = 0.0) -> IntegerForm:
    """``values`` (finite, ``(frames, columns)``) in representation ``rep``, with its exceptions and signs."""
    ints = to_ints(rep, values, decimals, quantum)
    return with_exceptions(IntegerForm(rep, ints, _NONE, np.zeros(0), _NONE, quantum), values, decimals)


_NONE = np.zeros(0, dtype=np.int64)


def with_exceptions(form: IntegerForm, values: np.ndarray, decimals: np.ndarray | None = None) -> IntegerForm:
    """``form`` with the exceptions and negative zeros that make it give back ``values`` exactly."""
    back = form_values(form, decimals)
    got, want = back.view(np.int64).ravel(), values.view(np.int64).ravel()
    wrong = got != want
    negzero = wrong & (want == _SIGN) & (got == 0)
    exc = np.flatnonzero(wrong & ~negzero)
    form.exceptions, form.exact, form.negzero = exc, values.ravel()[exc].copy(), np.flatnonzero(negzero)
    return form


def form_values(form: IntegerForm, decimals: np.ndarray | None = None) -> np.ndarray:
    """The values the integers of ``form`` give (exceptions and signs not applied)."""
    if form.rep != REP_COLUMNS:
        return from_ints(form.rep, form.ints, decimals, form.quantum)
    if form.columns is None:
        raise ValueError("per-column representations missing")
    reps, decs = form.columns
    out = np.empty(form.ints.shape)
    for rep in np.unique(reps).tolist():
        cols = np.flatnonzero(reps == rep)
        out[:, cols] = from_ints(rep, form.ints[:, cols], decs[cols], form.quantum)
    return out


def apply_exceptions(form: IntegerForm, decimals: np.ndarray | None = None) -> np.ndarray:
    """The exact ``(frames, columns)`` values of an integer form (inverse of :func:`integer_form`)."""
    values = form_values(form, decimals)
    flat = values.reshape(-1)
    flat[form.negzero] = -0.0
    flat[form.exceptions] = form.exact
    return values


def candidates(values: np.ndarray, decimals: np.ndarray | None, quantum: float | None) -> list[tuple[int, float]]:
    """Representations worth trying for a clip: ``(rep, quantum)`` pairs, most specific first."""
    reps: list[tuple[int, float]] = []
    if quantum is not None and quantum > 0 and np.isfinite(quantum):
        reps.append((REP_QUANTUM, float(quantum)))
    if decimals is not None:
        reps += [(REP_DECIMAL, 0.0), (REP_F32_DECIMAL, 0.0)]
    if not reps and values.size:
        found = float32_quantum(values)
        if found:
            reps.append((REP_F32_QUANTUM, found))
    reps += [(REP_FLOAT32, 0.0), (REP_SHORT_DECIMAL, 0.0), (REP_FLOAT64, 0.0)]
    return reps


def float32_quantum(values: np.ndarray) -> float:
    """The scale ``q`` (file units) if most values are ``float32(n * q)`` for integers ``n``, else 0.

    ``q`` is first guessed as a low percentile of the nonzero steps between frames, then refined by least
    squares on ``n = round(value / q)``, first on small values (where ``n`` cannot be wrong); the candidate
    (or its float32 rounding) is kept if it gives back at least 90 % of the values exactly.
    """
    with np.errstate(all="ignore"):
        return _float32_quantum(values)


def _float32_quantum(values: np.ndarray) -> float:
    v = values[np.isfinite(values)]
    if v.size < 16 or not np.array_equal(v.astype(np.float32).astype(np.float64), v):
        return 0.0
    steps = np.abs(np.diff(values, axis=0)).ravel()
    steps = steps[np.isfinite(steps) & (steps > 0)]
    if steps.size < 16:
        return 0.0
    guess = float(np.percentile(steps, 1))
    if not guess > 0 or np.abs(v).max() / guess > 2.0**30:
        return 0.0
    q = guess
    for rel in (2e-3, 2e-6, 0.0):  # refine on values small enough for round(v / q) to be right
        small = v[np.abs(v) <= 0.2 * q / rel] if rel else v
        n = np.round(small / q)
        nn = float(np.dot(n, n))
        if nn == 0:
            return 0.0
        q = float(np.dot(n, small)) / nn
    best, share = 0.0, 0.9
    for cand in (q, float(np.float32(q))):
        if not cand > 0:
            continue
        back = (np.round(v / cand) * cand).astype(np.float32).astype(np.float64)
        hit = float(np.mean(back == v))
        if hit >= share:
            best, share = cand, hit
    return best


def estimated_bits(form: IntegerForm) -> float:
    """A quick estimate of a form's coded size in bits: ``log2`` of its second differences, plus 80 bits per
    exception (its index and bits) and 8 per negative zero."""
    x = form.ints
    if x.shape[0] > 2:
        d2 = np.abs(x[2:] - 2 * x[1:-1] + x[:-2]).astype(np.float64)
        body = float(np.log2(1.0 + d2).sum())
    else:
        body = float(np.log2(1.0 + np.abs(x).astype(np.float64)).sum())
    return body + 80.0 * form.exceptions.size + 8.0 * form.negzero.size


def choose_form(values: np.ndarray, decimals: np.ndarray | None, quantum: float | None) -> IntegerForm:
    """The representation of ``values`` with the smallest :func:`estimated_bits` (exact whichever wins)."""
    best: IntegerForm | None = None
    best_bits = np.inf
    for rep, q in candidates(values, decimals, quantum):
        if best is not None and rep == REP_FLOAT64 and best.exceptions.size * 4 < values.size:
            break  # float64 bit patterns only when nothing else fits most values
        if best is not None and best.rep == REP_DECIMAL and not best.exceptions.size and rep != REP_F32_DECIMAL \
                and decimals is not None and int(np.max(decimals, initial=0)) <= 5:
            break  # text with few decimals, all fitting: the float forms cannot do better
        form = integer_form(rep, values, decimals, q)
        bits = estimated_bits(form)
        if bits < best_bits:
            best, best_bits = form, bits
    assert best is not None
    return best
