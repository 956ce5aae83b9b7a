"""Build the self-contained viewer page: one HTML file, data embedded, no network access.

Positions are stored as int16 over the clip's bounding box (resolution: box size / 65534, a fraction of a
millimetre for a human clip), errors as uint8 relative to the clip's largest error, both base64 in a JSON
block the page's own script reads. Output is deterministic: the same input gives the same bytes.

The page itself is package data in ``assets/``: ``viewer.html`` with ``viewer.css`` and ``viewer.js`` put in
place, no external resource at all. Its script draws with the 2D canvas API: a perspective camera that orbits a
target, depth-sorted bones and points, a ground grid with shadows, and an error strip.
"""

from __future__ import annotations

import base64
import json
import math
from functools import cache
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.io.common import atomic_write
from mocapz.viewer.data import ViewData, color_scales, default_yaw

MISSING_I16 = -32768
MISSING_U8 = 255
PLACEHOLDER = "__MOCAPZ_DATA__"  # in viewer.html: replaced by the clip's JSON
ASSET_MARKERS = (("__MOCAPZ_CSS__\n", "viewer.css"), ("__MOCAPZ_JS__\n", "viewer.js"))  # lines of viewer.html


def _asset(name: str) -> str:
    return files("mocapz.viewer").joinpath("assets", name).read_text(encoding="utf-8")


@cache
def page_template() -> str:
    """The page without its data: ``viewer.html``, each marker line replaced by its file, ``PLACEHOLDER`` kept."""
    html = _asset("viewer.html")
    for marker, name in ASSET_MARKERS:
        if html.count(marker) != 1:
            raise RuntimeError(f"viewer.html: expected one line {marker.strip()!r}")
        html = html.replace(marker, _asset(name), 1)
    return html


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def quantize_positions(arrays: list[np.ndarray]) -> tuple[list[np.ndarray], list[float], list[float]]:
    """Little-endian int16 codes of ``(frames, points, 3)`` arrays sharing one quantizer per axis.

    Returns the codes (``-32768`` for NaN), the per-axis lower bound and step: ``x = lo + (q + 32767) * step``.
    """
    stacked = np.concatenate([a.reshape(-1, 3) for a in arrays])
    finite = np.isfinite(stacked).all(axis=1)
    if finite.any():
        lo = stacked[finite].min(axis=0)
        hi = stacked[finite].max(axis=0)
    else:
        lo = hi = np.zeros(3)
    step = np.maximum((hi - lo) / 65534.0, 1e-12)
    out = []
    for a in arrays:
        ok = np.isfinite(a).all(axis=-1, keepdims=True)
        q = np.clip(np.rint((np.nan_to_num(a) - lo) / step), 0, 65534) - 32767
        out.append(np.where(ok, q, MISSING_I16).astype("<i2"))
    return out, [float(v) for v in lo], [float(v) for v in step]


def quantize_errors(errors: np.ndarray, emax: float) -> np.ndarray:
    """uint8 codes ``round(254 * e / emax)``, 255 for NaN."""
    ok = np.isfinite(errors)
    scale = 254.0 / emax if emax > 0 else 0.0
    q = np.clip(np.rint(np.where(ok, errors, 0.0) * scale), 0, 254)
    return np.where(ok, q, MISSING_U8).astype(np.uint8)


def _num(v: float) -> float | None:
    """A JSON-safe float (None for NaN / inf), rounded to float32 precision to keep the page small."""
    return float(f"{v:.7g}") if math.isfinite(v) else None


def page_data(view: ViewData) -> dict[str, Any]:
    """The JSON object the page's script reads."""
    arrays = [view.original] + ([view.decoded] if view.decoded is not None else [])
    codes, lo, step = quantize_positions(arrays)
    emax = view.error_max
    fmax, fmean = view.frame_error_stats()
    if view.errors is not None:
        ok = np.isfinite(view.errors)
        e0 = np.where(ok, view.errors, 0.0)
        pmax = e0.max(axis=0, initial=0.0)
        prms = np.sqrt((e0**2).sum(axis=0) / np.maximum(ok.sum(axis=0), 1))
        order = [int(i) for i in np.argsort(-pmax, kind="stable")]
    else:
        pmax = prms = np.zeros(view.n_points)
        order = []
    return {
        "format": "mocapz-view/1",
        "name": view.name,
        "kind": view.kind,
        "frames": view.n_frames,
        "points": view.n_points,
        "fps": _num(view.frame_rate),
        "source_fps": _num(view.frame_rate * view.step),
        "step": view.step,
        "first_frame": view.first_frame,
        "source_frames": view.source_frames,
        "names": view.names,
        "bones": [int(i) for i in view.bones.reshape(-1)],
        "quant": {"lo": lo, "step": step},
        "original": _b64(codes[0]),
        "decoded": _b64(codes[1]) if len(codes) > 1 else None,
        "errors": _b64(quantize_errors(view.errors, emax)) if view.errors is not None else None,
        "err_max": _num(emax),
        "frame_max": _b64(fmax.astype("<f4")),
        "frame_mean": _b64(fmean.astype("<f4")),
        "point_max": [_num(v) for v in pmax],
        "point_rms": [_num(v) for v in prms],
        "point_order": order,
        "center": _b64(view.center.astype("<f4")),
        "floor": _num(view.floor),
        "height": _num(view.height),
        "grid": _num(view.grid),
        "unit": view.unit,
        "unit_scale": _num(view.unit_scale),
        "scales": [[label, _num(v)] for label, v in color_scales(view)],
        "view": {"yaw": _num(default_yaw(view)), "pitch": 0.22, "dist": _num(2.8 * view.height)},
        "figures": [list(f) for f in view.figures],
        "decoded_label": view.decoded_label,
        "notes": view.notes,
    }


def build_page(view: ViewData) -> str:
    """The complete HTML page for ``view``.

    The JSON is embedded with ``/`` and ``<`` escaped, so no text from the data (joint names, paths) can
    close the script element or read as a URL.
    """
    text = json.dumps(page_data(view), ensure_ascii=True, separators=(",", ":"), allow_nan=False)
    text = text.replace("/", "\\/").replace("<", "\\u003c").replace(">", "\\u003e")
    return page_template().replace(PLACEHOLDER, text, 1)


def write_page(view: ViewData, path: str | Path, force: bool = False) -> int:
    """Write the page atomically (an existing file is kept unless ``force``); return its size in bytes."""
    data = build_page(view).encode("utf-8")
    atomic_write(path, lambda tmp: tmp.write_bytes(data), force=force)
    return len(data)
