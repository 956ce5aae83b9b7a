"""Lossless encoder.

Sections: ``rep`` (the representation byte; the quantum as float64 for the quantum forms; per-column
representations and decimals for ``REP_COLUMNS``, :mod:`.columns`), ``gaps``
(marker clips with missing samples: packed mask), ``const`` (columns whose observed values never change),
``head`` (first frame, and first differences of the other columns), ``coef`` (cross-channel predictor
coefficients), ``res`` (prediction residuals of the observed samples, :mod:`.coding`), ``exc`` and
``negz`` (per-value exceptions and ``-0`` positions, present only when there are some).
"""

from __future__ import annotations

import struct

import numpy as np

from mocapz.codecs.gaps import pack_mask
from mocapz.codecs.lossless import fast
from mocapz.codecs.lossless.coding import encode_indices, encode_residuals, pack_small
from mocapz.codecs.lossless.columns import column_form, pack_columns
from mocapz.codecs.lossless.integers import (
    QUANTUM_REPS,
    REP_COLUMNS,
    REP_DECIMAL,
    IntegerForm,
    choose_form,
    estimated_bits,
    form_values,
)
from mocapz.codecs.lossless.predict import (
    COEF_SHIFT,
    choose_predictors,
    coding_order,
    cross_term,
    pack_predictors,
    shared_fit,
)
from mocapz.codecs.lossless.pursuit import choose_shared
from mocapz.format.entropy import pack_uint64, write_uvarint, zigzag
from mocapz.model.motion import AnyMotion, MarkerMotion, Motion


def column_groups(motion: AnyMotion) -> list[list[int]]:
    """Columns that predict each other: one group per joint (skeleton) or per marker (x, y, z)."""
    if isinstance(motion, Motion):
        return [list(range(s.start, s.stop)) for s in motion.skeleton.channel_slices()]
    return [[3 * m, 3 * m + 1, 3 * m + 2] for m in range(motion.n_markers)]


def value_matrix(motion: AnyMotion) -> tuple[np.ndarray, np.ndarray | None]:
    """``(frames, columns)`` values with gaps set to 0, and the gap mask (True = missing) or None."""
    if isinstance(motion, Motion):
        return motion.channels, None
    pos = motion.positions.reshape(motion.n_frames, 3 * motion.n_markers)
    gaps = ~np.isfinite(pos)
    if not gaps.any():
        return pos, None
    return np.where(gaps, 0.0, pos), gaps


def motion_decimals(motion: AnyMotion, cols: int) -> np.ndarray | None:
    """``(columns,)`` decimals of the source text, or None."""
    if motion.decimals is None:
        return None
    return np.broadcast_to(np.asarray(motion.decimals, dtype=np.int64), (cols,))


def encode(motion: AnyMotion, **options: object) -> dict[str, bytes]:
    """Encode a motion losslessly; returns the container sections."""
    if options:
        from mocapz.errors import OptionError

        raise OptionError(f"the lossless codec takes no options (got {', '.join(options)})")
    values, gaps = value_matrix(motion)
    whole = motion.metadata.get("block_of")  # a block of a longer clip: the compiled kernels where it pays for them
    if whole is not None:
        fast.expect(whole.clip.n_frames * values.shape[1])
    decimals = motion_decimals(motion, values.shape[1])
    form = choose_form(values, decimals, motion.quantum if isinstance(motion, MarkerMotion) else None)
    fits = form.rep in (REP_DECIMAL, *QUANTUM_REPS) and form.exceptions.size * 1000 <= values.size
    if not fits and values.shape[0] > 2 and values.shape[1]:
        by_column, bits = column_form(values)
        if bits < 0.97 * estimated_bits(form):  # the estimates are rough: only a clear gain
            form = by_column
    sections: dict[str, bytes] = {"rep": bytes([form.rep])}
    if form.rep in QUANTUM_REPS:
        sections["rep"] += struct.pack("<d", form.quantum)
    elif form.rep == REP_COLUMNS:
        sections["rep"] = pack_columns(form)
    if gaps is not None:
        sections["gaps"] = pack_mask(gaps)
    sections.update(_value_sections(form, decimals))
    sections.update(_integer_sections(form.ints, gaps, column_groups(motion)))
    return sections


def _value_sections(form: IntegerForm, decimals: np.ndarray | None) -> dict[str, bytes]:
    """``exc`` (uvarint size of the position list, the positions, then the XOR of each exact value's bits with
    its placeholder's) and ``negz``.

    Positions are column-major (``column * frames + frame``), where the odd values of one channel cluster."""
    frames, cols = form.ints.shape
    out: dict[str, bytes] = {}
    if form.exceptions.size:
        t, c = np.divmod(form.exceptions, cols)
        order = np.argsort(c * frames + t, kind="stable")
        idx = form.exceptions[order]
        placeholder = form_values(form, decimals).ravel()[idx]
        xor = placeholder.view(np.uint64) ^ form.exact[order].view(np.uint64)
        pos = encode_indices(np.sort(c * frames + t))
        out["exc"] = write_uvarint(len(pos)) + pos + pack_small(xor)
    if form.negzero.size:
        t, c = np.divmod(form.negzero, cols)
        out["negz"] = encode_indices(np.sort(c * frames + t))
    return out


def _integer_sections(x: np.ndarray, gaps: np.ndarray | None, groups: list[list[int]]) -> dict[str, bytes]:
    """``const``, ``head``, ``coef`` and ``res`` for the integers ``x`` ``(frames, columns)``.

    Missing samples are filled so that their second difference equals the cross-channel prediction: their
    residual is then 0 and is not coded (the decoder knows where the gaps are)."""
    frames, cols = x.shape
    if frames == 0:
        return {}
    x = x.copy()
    observed = np.ones_like(x, dtype=bool) if gaps is None else ~gaps
    const = np.ones(cols, dtype=bool)
    for c in range(cols):
        seen = x[observed[:, c], c]
        const[c] = seen.size == 0 or bool((seen == seen[0]).all())
        fill = seen[0] if seen.size else 0
        if const[c]:
            x[:, c] = fill
        elif not observed[0, c]:
            x[0, c] = fill
    active = np.flatnonzero(~const)
    if frames > 1:
        hold = active[~observed[1, active]]
        x[1, hold] = x[0, hold]
    d1 = (x[1] - x[0])[active] if frames > 1 else np.zeros(0, dtype=np.int64)
    out = {"const": pack_mask(const), "head": pack_uint64(zigzag(np.concatenate([x[0], d1])))}
    if frames <= 2 or not active.size:
        return out
    order = coding_order([[c for c in g if not const[c]] for g in groups])
    residual = np.empty((frames - 2, len(order)), dtype=np.int64)
    coded = observed[2:, order]
    table: list[tuple[list[int], np.ndarray]] = []
    if gaps is None:  # every second difference is final from the start: one pass, one shared Gram matrix
        d2 = x[2:] - 2 * x[1:-1] + x[:-2]
        shared = shared_fit(d2, order)
        every = np.arange(frames - 2)
        d2t = np.ascontiguousarray(d2.T)  # a column's predictors are rows here (contiguous gathers)
        if shared is not None:
            table = choose_shared(shared, order, frames - 2)
        else:
            table = [choose_predictors(d2, c, order[:k], every) for k, c in enumerate(order)]
        for k, c in enumerate(order):
            residual[:, k] = d2t[c] - _cross_rows(d2t, *table[k])
        out["coef"] = pack_predictors(order, table)
        out["res"] = encode_residuals(residual, coded)
        return out
    d2 = np.zeros((frames - 2, cols), dtype=np.int64)
    for k, c in enumerate(order):
        rows = np.flatnonzero(observed[2:, c] & observed[1:-1, c] & observed[:-2, c])
        d2[:, c] = x[2:, c] - 2 * x[1:-1, c] + x[:-2, c]
        preds, coef = choose_predictors(d2, c, order[:k], rows)
        table.append((preds, coef))
        cross = cross_term(d2, preds, coef)
        if not coded[:, k].all():
            _fill_gaps(x[:, c], ~coded[:, k], cross)
            d2[:, c] = x[2:, c] - 2 * x[1:-1, c] + x[:-2, c]
        residual[:, k] = np.where(coded[:, k], d2[:, c] - cross, 0)
    out["coef"] = pack_predictors(order, table)
    out["res"] = encode_residuals(residual, coded)
    return out


def _cross_rows(d2t: np.ndarray, preds: list[int], coef: np.ndarray) -> np.ndarray:
    """:func:`~.predict.cross_term` on transposed second differences ``(columns, frames)`` (same integers)."""
    if not preds:
        return np.zeros(d2t.shape[1], dtype=np.int64)
    acc = np.asarray(coef, dtype=np.int64) @ d2t[preds]
    return (acc + (1 << (COEF_SHIFT - 1))) >> COEF_SHIFT


def _fill_gaps(col: np.ndarray, missing: np.ndarray, cross: np.ndarray) -> None:
    """Set ``col[t + 2]`` for every missing ``t`` so that its second difference is ``cross[t]`` (in place)."""
    v = col.tolist()
    cr = cross.tolist()
    for t in np.flatnonzero(missing).tolist():  # wrapping int64 arithmetic, as the decoder's numpy sums
        v[t + 2] = ((2 * v[t + 1] - v[t] + cr[t] + (1 << 63)) & ((1 << 64) - 1)) - (1 << 63)
    col[:] = np.asarray(v, dtype=np.int64)
