"""Lossless decoder (the sections are described in :mod:`.encode`)."""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from mocapz.codecs.gaps import unpack_mask
from mocapz.codecs.lossless import fast
from mocapz.codecs.lossless.coding import decode_indices, decode_residuals, residual_shape, unpack_small
from mocapz.codecs.lossless.columns import unpack_columns
from mocapz.codecs.lossless.integers import (
    QUANTUM_REPS,
    REP_COLUMNS,
    REP_DECIMAL,
    REP_F32_DECIMAL,
    REPRESENTATIONS,
    IntegerForm,
    apply_exceptions,
    form_values,
)
from mocapz.codecs.lossless.predict import coding_order, cross_term, unpack_predictors
from mocapz.errors import FormatError
from mocapz.format.entropy import read_uvarint, unpack_uint64, unzigzag
from mocapz.model.header import ClipHeader


def _groups(header: ClipHeader) -> tuple[int, list[list[int]]]:
    """Column count and the columns of each joint (or marker): cross-channel prediction stays in a group."""
    if header.skeleton is not None:
        groups = [list(range(s.start, s.stop)) for s in header.skeleton.channel_slices()]
        return header.skeleton.n_channels, groups
    m = len(header.labels)
    return 3 * m, [[3 * i, 3 * i + 1, 3 * i + 2] for i in range(m)]


def decode(sections: dict[str, bytes], header: ClipHeader) -> Any:
    """Decode lossless sections back into the exact motion."""
    frames = header.frames
    cols, groups = _groups(header)
    if header.batch_frames:  # a block of a long read: the compiled kernels where the read pays for them
        fast.expect(header.batch_frames * cols)
    try:
        rep, quantum = _rep(sections["rep"])
        columns = unpack_columns(sections["rep"], cols) if rep == REP_COLUMNS else None
        gaps = unpack_mask(sections["gaps"], (frames, cols)) if "gaps" in sections else None
        x = _decode_ints(sections, frames, cols, groups, gaps)
    except KeyError as exc:
        raise FormatError(None, f"corrupted lossless stream (missing section {exc})") from None
    decimals = None
    if rep in (REP_DECIMAL, REP_F32_DECIMAL):
        if header.decimals is None:
            raise FormatError(None, "corrupted lossless stream (decimals missing)")
        decimals = np.broadcast_to(np.asarray(header.decimals, dtype=np.int64), (cols,))
    form = IntegerForm(rep, x, np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.int64), quantum, columns)
    _read_exceptions(sections, form, decimals)
    values = apply_exceptions(form, decimals)
    if gaps is not None:
        values = np.where(gaps, np.nan, values)
    return header.motion(values.reshape(header.value_shape))


def _rep(data: bytes) -> tuple[int, float]:
    if len(data) < 1 or data[0] not in REPRESENTATIONS:
        raise FormatError(None, f"corrupted lossless stream (representation {data[:8].hex() or 'missing'})")
    if data[0] == REP_COLUMNS:
        return data[0], 0.0
    if data[0] not in QUANTUM_REPS:
        if len(data) != 1:
            raise FormatError(None, "corrupted lossless stream (representation)")
        return data[0], 0.0
    if len(data) != 9:
        raise FormatError(None, "corrupted lossless stream (quantum)")
    (q,) = struct.unpack("<d", data[1:])
    if not (np.isfinite(q) and q > 0):
        raise FormatError(None, f"corrupted lossless stream (quantum {q})")
    return data[0], q


def _read_exceptions(sections: dict[str, bytes], form: IntegerForm, decimals: np.ndarray | None) -> None:
    """Fill ``form``'s exceptions and negative zeros from the ``exc`` / ``negz`` sections (column-major)."""
    frames, cols = form.ints.shape
    size = frames * cols

    def row_major(cm: np.ndarray) -> np.ndarray:
        c, t = np.divmod(cm, max(frames, 1))
        return t * cols + c

    if "negz" in sections:
        form.negzero = row_major(decode_indices(sections["negz"], size))
    if "exc" in sections:
        data = sections["exc"]
        n, pos = read_uvarint(data, 0)
        if pos + n > len(data):
            raise FormatError(None, "truncated lossless stream (exceptions)")
        idx = row_major(decode_indices(data[pos : pos + n], size))
        xor = unpack_small(data[pos + n :], idx.size)
        placeholder = form_values(form, decimals).ravel()[idx]
        form.exceptions = idx
        form.exact = (placeholder.view(np.uint64) ^ xor).view(np.float64)


def _decode_ints(sections: dict[str, bytes], frames: int, cols: int, groups: list[list[int]],
                 gaps: np.ndarray | None) -> np.ndarray:
    """The ``(frames, cols)`` integers; every stream is checked against the header before they are allocated."""
    if frames == 0:
        return np.zeros((0, cols), dtype=np.int64)
    const = unpack_mask(sections["const"], (cols,))  # packed bits, as pack_mask writes them
    active = np.flatnonzero(~const)
    head = unzigzag(unpack_uint64(sections["head"], cols + (active.size if frames > 1 else 0)))
    d1 = head[cols:]
    d2 = None
    if frames > 2 and active.size:
        order = coding_order([[c for c in g if not const[c]] for g in groups])
        shape, _ = residual_shape(sections["res"])
        if shape != (frames - 2, len(order)):
            raise FormatError(None, f"corrupted lossless stream (residuals for {shape}, {(frames - 2, len(order))} "
                                    f"expected)")
        observed = np.ones((frames - 2, len(order)), dtype=bool) if gaps is None else ~gaps[2:, order]
        residual = decode_residuals(sections["res"], observed)
        npred, pidx, pcoef = unpack_predictors(order, sections["coef"])
        kern = fast.kernels()
        if kern is not None:
            x = np.broadcast_to(head[:cols], (frames, cols)).copy()
            kern.undo_prediction(residual, np.asarray(order, dtype=np.int64), npred, pidx, pcoef,
                                 active.astype(np.int64), d1.astype(np.int64), x)
            return x
        d2 = np.zeros((frames - 2, cols), dtype=np.int64)
        for k, c in enumerate(order):
            m = int(npred[k])
            d2[:, c] = residual[:, k] + cross_term(d2, pidx[k, :m].tolist(), pcoef[k, :m])
    x = np.broadcast_to(head[:cols], (frames, cols)).copy()
    if frames == 1:
        return x
    if d2 is None:
        x[1, active] += d1
        return x
    slopes = np.concatenate([d1[None, :], d1[None, :] + np.cumsum(d2[:, active], axis=0)], axis=0)
    x[1:, active] = x[0, active] + np.cumsum(slopes, axis=0)
    return x

