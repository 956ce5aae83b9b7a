"""Lossless decoder."""

from __future__ import annotations

from typing import Any

import numpy as np

from mocapz.codecs.gaps import unpack_mask
from mocapz.codecs.lossless.integers import REP_DECIMAL, REPRESENTATIONS, from_integers
from mocapz.codecs.lossless.predict import cross_term, predictor_columns
from mocapz.errors import FormatError
from mocapz.format.entropy import decode_int_matrix, unpack_uint64, unzigzag
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
    try:
        rep = sections["rep"]
        if len(rep) != 1 or rep[0] not in REPRESENTATIONS:
            raise FormatError(None, f"corrupted lossless stream (representation {rep[:8].hex() or 'missing'})")
        gaps = unpack_mask(sections["gaps"], (frames, cols)) if "gaps" in sections else None
        x = _decode_ints(sections, frames, cols, groups)
    except KeyError as exc:
        raise FormatError(None, f"corrupted lossless stream (missing section {exc})") from None
    decimals = None
    if rep[0] == REP_DECIMAL:
        dec = header.decimals
        if dec is None:
            raise FormatError(None, "corrupted lossless stream (decimals missing)")
        decimals = np.broadcast_to(np.asarray(dec, dtype=np.int64), (cols,))
    values = from_integers(rep[0], x, decimals)
    if gaps is not None:
        values = np.where(gaps, np.nan, values)
    return header.motion(values.reshape(header.value_shape))


def _decode_ints(sections: dict[str, bytes], frames: int, cols: int, groups: list[list[int]]) -> np.ndarray:
    """The ``(frames, cols)`` integers; every stream is checked against the header before they are allocated."""
    if frames == 0:
        return np.zeros((0, cols), dtype=np.int64)
    const = unpack_mask(sections["const"], (cols,))  # packed bits, as pack_mask writes them
    active = np.flatnonzero(~const)
    head = unzigzag(unpack_uint64(sections["head"], cols + (active.size if frames > 1 else 0)))
    d1 = head[cols:]
    d2 = None
    if frames > 2 and active.size:
        order = predictor_columns([[c for c in g if not const[c]] for g in groups if any(not const[c] for c in g)])
        residual = decode_int_matrix(sections["res"], (frames - 2, len(order)))
        coefs = unzigzag(unpack_uint64(sections["coef"], sum(len(p) for _, p in order)))
        d2 = np.zeros((frames - 2, cols), dtype=np.int64)
        pos = 0
        for k, (c, preds) in enumerate(order):
            coef = coefs[pos : pos + len(preds)]
            pos += len(preds)
            d2[:, c] = residual[:, k] + cross_term(d2, preds, coef)
    x = np.broadcast_to(head[:cols], (frames, cols)).copy()
    if frames == 1:
        return x
    if d2 is None:
        x[1, active] += d1
        return x
    slopes = np.concatenate([d1[None, :], d1[None, :] + np.cumsum(d2[:, active], axis=0)], axis=0)
    x[1:, active] = x[0, active] + np.cumsum(slopes, axis=0)
    return x
