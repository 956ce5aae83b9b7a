"""Lossless encoder."""

from __future__ import annotations

import numpy as np

from mocapz.codecs.gaps import fill_hold, pack_mask
from mocapz.codecs.lossless.integers import to_integers
from mocapz.codecs.lossless.predict import cross_term, fit_coef, predictor_columns
from mocapz.format.entropy import encode_int_matrix, pack_uint64, zigzag
from mocapz.model.motion import AnyMotion, Motion


def column_groups(motion: AnyMotion) -> list[list[int]]:
    """Columns that predict each other: one group per joint (skeleton) or per marker (x, y, z)."""
    if isinstance(motion, Motion):
        return [list(range(s.start, s.stop)) for s in motion.skeleton.channel_slices()]
    return [[3 * m, 3 * m + 1, 3 * m + 2] for m in range(motion.n_markers)]


def value_matrix(motion: AnyMotion) -> tuple[np.ndarray, np.ndarray | None]:
    """``(frames, columns)`` values with gaps filled (for prediction), and the gap mask or None."""
    if isinstance(motion, Motion):
        return motion.channels, None
    pos = motion.positions.reshape(motion.n_frames, 3 * motion.n_markers)
    gaps = ~np.isfinite(pos)
    if not gaps.any():
        return pos, None
    return fill_hold(pos, gaps), gaps


def encode(motion: AnyMotion, **options: object) -> dict[str, bytes]:
    """Encode a motion losslessly; returns the container sections."""
    if options:
        from mocapz.errors import OptionError

        raise OptionError(f"the lossless codec takes no options (got {', '.join(options)})")
    values, gaps = value_matrix(motion)
    decimals = motion.decimals if isinstance(motion, Motion) else (
        None if motion.decimals is None else np.full(values.shape[1], motion.decimals)
    )
    rep, x = to_integers(values, decimals)
    frames, cols = x.shape
    sections: dict[str, bytes] = {"rep": bytes([rep])}
    if gaps is not None:
        sections["gaps"] = pack_mask(gaps)
    if frames == 0:
        return sections
    const = (x == x[0]).all(axis=0)
    d1 = (x[1] - x[0])[~const] if frames > 1 else np.zeros(0, dtype=np.int64)
    sections["head"] = pack_uint64(zigzag(np.concatenate([x[0], d1])))
    sections["const"] = pack_mask(const)
    if frames <= 2 or const.all():
        return sections
    d2 = x[2:] - 2 * x[1:-1] + x[:-2]
    groups = [[c for c in g if not const[c]] for g in column_groups(motion)]
    order = predictor_columns([g for g in groups if g])
    residual = np.empty((frames - 2, len(order)), dtype=np.int64)
    coefs: list[int] = []
    for k, (c, preds) in enumerate(order):
        coef = fit_coef(d2, c, preds)
        coefs.extend(coef.tolist())
        residual[:, k] = d2[:, c] - cross_term(d2, preds, coef)
    sections["coef"] = pack_uint64(zigzag(np.asarray(coefs, dtype=np.int64)))
    sections["res"] = encode_int_matrix(residual)
    return sections
