"""How far a decoded C3D clip's analog channels and model-output tracks are from the original's, in their own
units, and whether the rest of the file (parameters, residual words) came back exactly.

These are not marker errors: METRICS.md's figures leave them out (:mod:`mocapz.metrics.figures`); here each
kind of value is measured on its own. Values a sample's residual word marks missing are left out.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mocapz.model.c3d_extras import C3DExtras
from mocapz.model.motion import AnyMotion


def _extras(motion: AnyMotion) -> C3DExtras | None:
    extras = motion.metadata.get("c3d")
    return extras if isinstance(extras, C3DExtras) else None


def _max(err: np.ndarray) -> float:
    finite = err[np.isfinite(err)]
    return float(finite.max()) if finite.size else 0.0


def extras_errors(original: AnyMotion, decoded: AnyMotion) -> dict[str, Any] | None:
    """``None`` unless both motions carry C3D extras of the same shape; else::

        {"parameters_equal": bool, "residuals_equal": bool,
         "analogs": {"channels": n, "max_err": float, "exact": bool} (in each channel's unit),
         "tracks": {"ANGLES": {"tracks": n, "unit": "deg", "max_err": float, "exact": bool}, ...}}

    ``max_err`` is the largest difference of any one value (x, y or z of a track).
    """
    a, b = _extras(original), _extras(decoded)
    if a is None or b is None or a.analog_words.shape != b.analog_words.shape or \
            a.track_words.shape != b.track_words.shape or a.residual_words.shape != b.residual_words.shape:
        return None
    out: dict[str, Any] = {"parameters_equal": a.params == b.params,
                           "residuals_equal": bool(np.array_equal(a.residual_words, b.residual_words))}
    if a.channels:
        unit = a.analog_scales if a.analog_scales is not None else np.ones(a.channels)
        err = np.abs(b.analog_values() - a.analog_values()) * unit[None, :]
        out["analogs"] = {"channels": a.channels, "max_err": _max(err),
                          "exact": bool(np.array_equal(a.analog_words, b.analog_words))}
    tracks: dict[str, Any] = {}
    if a.track_index.size:
        err = np.abs(b.track_values() - a.track_values())
        kinds = np.array(a.track_kinds)
        for kind in dict.fromkeys(a.track_kinds):
            sel = kinds == kind
            units = sorted({u for u, s in zip(a.track_units, sel, strict=True) if s})
            tracks[kind] = {"tracks": int(sel.sum()), "unit": ",".join(units), "max_err": _max(err[:, sel]),
                            "exact": bool(np.array_equal(a.track_words[:, sel], b.track_words[:, sel]))}
    out["tracks"] = tracks
    return out


def describe(errors: dict[str, Any]) -> str:
    """One line of :func:`extras_errors`' figures."""
    parts = []
    ana = errors.get("analogs")
    if ana:
        parts.append(f"{ana['channels']} analog channels " + ("exact" if ana["exact"] else
                                                               f"within {ana['max_err']:.4g} (their units)"))
    for kind, t in errors["tracks"].items():
        parts.append(f"{t['tracks']} {kind.lower()} " + ("exact" if t["exact"] else
                                                          f"within {t['max_err']:.4g} {t['unit']}".rstrip()))
    parts.append("parameters " + ("exact" if errors["parameters_equal"] else "changed"))
    parts.append("residuals " + ("exact" if errors["residuals_equal"] else "changed"))
    return ", ".join(parts)
