"""C3D marker files, read through ``ezc3d`` or, where ezc3d cannot read them, the pure-Python ``c3d``
package, and written back in their own storage (or, for a motion that did not come from a C3D file,
through ``ezc3d``).

Reading keeps the marker positions (``POINT:LABELS``, ``POINT:RATE``, ``POINT:UNITS``, first frame),
missing samples (a negative residual word or a non-finite value) as NaN, and everything else the file
holds in a :class:`~mocapz.model.c3d_extras.C3DExtras` (``metadata["c3d"]``, made by
:mod:`mocapz.io.c3d_raw`): the header and parameter section verbatim, residual words, analog samples,
the model outputs (points named in POINT:ANGLES / FORCES / MOMENTS / POWERS / REACTIONS, which are not
markers). :func:`write_c3d` writes them back byte for byte. For Python users ``metadata`` also holds the
markers' residuals, the analog channels as the reader scales them, their labels, units and rate.

Readers, chosen automatically. Before any reader sees a file it is checked by
:func:`mocapz.io.c3d_checks.check_c3d_file` (ezc3d segfaults on some corrupt parameter sections,
silently reads a truncated file as a shorter clip and raises bare C++ errors on garbage; the checks
refuse only what would crash or hang a reader). Then:

1. ``ezc3d``, unless it must not be given the file (SGI/MIPS storage; a POINT:FRAMES past the end of
   the file);
2. the ``c3d`` package (:mod:`mocapz.io.c3d_pure`) for those files and for the files ezc3d refuses
   although their structure passed the checks (c3d.org ``Dance.c3d``: header errors);
3. what neither reads becomes a :class:`FormatError` naming the file and both reasons.

``metadata["c3d_reader"]`` says which reader read the file and why: ``"ezc3d"`` or
``"c3d (<why not ezc3d>)"``. The marker positions and the extras are decoded from the file's words by
:mod:`mocapz.io.c3d_raw` whichever reader read it, so that a file comes back bit for bit in its storage.
"""
from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.errors import FormatError, MocapzError
from mocapz.io.c3d_checks import C3DLayout, check_c3d_file
from mocapz.io.c3d_raw import c3d_bytes, split_c3d
from mocapz.io.common import atomic_write
from mocapz.model.c3d_extras import C3DExtras
from mocapz.model.motion import MarkerMotion

FLOAT32_MAX = float(np.finfo(np.float32).max)
MAX_FRAMES = 65535  # ezc3d writes POINT:FRAMES and the header frame numbers as 16-bit integers


# ----------------------------------------------------------------------------------------------- reading


def read_c3d(path: str | os.PathLike[str]) -> MarkerMotion:
    """Read a C3D file into a :class:`MarkerMotion`.

    Returns:
        positions ``(frames, markers, 3)`` float64 in ``POINT:UNITS`` (float32 values for float C3D
        files), NaN where a sample is missing; ``metadata`` holds ``first_frame`` (1-based),
        ``residuals`` ``(frames, markers)``, ``point_scale``, ``point_descriptions`` and, when the file
        has analog channels, ``analogs`` ``(channels, samples)`` float64 with ``analog_labels``,
        ``analog_units``, ``analog_descriptions`` and ``analog_rate`` (Hz); ``c3d_reader`` is ``"ezc3d"``
        or, for a file ezc3d cannot read, ``"c3d (<why not ezc3d>)"`` (the ``c3d`` package).
    """
    path = Path(path)
    layout = check_c3d_file(path)
    c3d, reader = _load(path, layout)
    _check_frame_count(c3d, np.asarray(c3d["data"]["points"]).shape[2], path)
    labels, positions, extras = split_c3d(path, layout)
    params = c3d["parameters"]
    units = _first_string(params, "POINT", "UNITS")
    metadata = _metadata(path, c3d, layout, _marker_residuals(extras), extras.marker_index)
    metadata["c3d_reader"] = reader
    metadata["c3d"] = extras
    if units is None:
        metadata["units_note"] = "POINT:UNITS missing; millimetres assumed (the C3D default)"
    return MarkerMotion(
        labels=labels,
        positions=positions,
        quantum=extras.quantum,
        frame_rate=_point_rate(c3d, params, path),
        units=units or "mm",
        name=path.stem,
        source_format="c3d",
        decimals=None,
        metadata=metadata,
    )


def _marker_residuals(extras: C3DExtras) -> np.ndarray:
    """The markers' residuals ``(frames, markers)`` as ezc3d gives them: -1 for a missing sample (a
    negative residual word), else the word's high byte times the point's ``|scale|``."""
    words = np.trunc(extras.residual_values()[:, extras.marker_index])
    scales = extras.scales[extras.marker_index]
    with np.errstate(invalid="ignore"):
        return np.where(words < 0, -1.0, np.floor(words / 256) * scales[None, :])


def _metadata(path: Path, c3d: Any, layout: C3DLayout, residuals: np.ndarray,
              markers: np.ndarray) -> dict[str, Any]:
    params = c3d["parameters"]
    descriptions = _fit(_strings(params, "POINT", "DESCRIPTIONS"), layout.points, "")
    meta: dict[str, Any] = {
        "path": str(path),
        "file_bytes": path.stat().st_size,
        "first_frame": int(c3d["header"]["points"]["first_frame"]) + 1,
        "residuals": residuals,
        "point_scale": _first_number(params, "POINT", "SCALE", -1.0),
        "point_descriptions": [descriptions[i] for i in markers],
        "c3d_float": layout.header.is_float,
        "c3d_processor": layout.header.processor,
    }
    meta.update(_analog_metadata(c3d, params))
    return meta


def _load(path: Path, layout: C3DLayout) -> tuple[Any, str]:
    """The file read by ezc3d, or by the ``c3d`` package (:mod:`mocapz.io.c3d_pure`) when ezc3d must not
    be given it or refuses it; and which reader read it (with why ezc3d did not, for ``c3d``)."""
    if layout.ezc3d_unsafe:
        why = f"ezc3d not given the file: {layout.ezc3d_unsafe}"
    else:
        import ezc3d

        try:
            return ezc3d.c3d(str(path), extract_forceplat_data=False), "ezc3d"
        except Exception as exc:  # ezc3d raises RuntimeError, OSError, ValueError... from C++
            why = f"ezc3d: {_short(exc)}"
    from mocapz.io.c3d_pure import read_c3d_package

    try:
        return read_c3d_package(path, layout), f"c3d ({why})"
    except FormatError as exc:
        raise FormatError(path, f"not a readable C3D file ({why}; {exc.message})") from None


def _short(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return (text[0] if text else type(exc).__name__).removesuffix(": iostream error")


def _check_frame_count(c3d: Any, frames: int, path: Path) -> None:
    """ezc3d silently stops at the end of a truncated file: compare with the frames it was told."""
    info = c3d["header"]["points"]
    declared = int(info["last_frame"]) - int(info["first_frame"]) + 1
    if frames < declared:
        raise FormatError(path, f"truncated: {frames} frames of point data where the file declares {declared}")


def _param(params: Any, group: str, name: str) -> Any:
    try:
        return params[group][name]["value"]
    except KeyError:
        return None


def _strings(params: Any, group: str, name: str) -> list[str]:
    """A string list parameter with its ``NAME2``, ``NAME3``... continuations (over 255 entries)."""
    out: list[str] = []
    for key in [name] + [f"{name}{i}" for i in range(2, 100)]:
        value = _param(params, group, key)
        if value is None:
            break
        out.extend(str(v).strip() for v in np.asarray(value).ravel())
    return out


def _first_string(params: Any, group: str, name: str) -> str | None:
    values = _strings(params, group, name)
    return values[0] if values and values[0] else None


def _first_number(params: Any, group: str, name: str, default: float) -> float:
    value = _param(params, group, name)
    arr = np.asarray(value, dtype=np.float64).ravel() if value is not None else np.empty(0)
    return float(arr[0]) if arr.size and np.isfinite(arr[0]) else default


def _fit(values: list[str], n: int, fill: str | None) -> list[str]:
    """``n`` entries: ``values`` cut or padded with ``fill``; ``fill=None`` (labels) names an empty or
    absent entry ``*<number>``, as the TRC reader names unnamed columns."""
    out = [str(v) for v in values[:n]] + [""] * max(n - len(values), 0)
    if fill is not None:
        return [v if i < len(values) else fill for i, v in enumerate(out)]
    return [v or f"*{i + 1}" for i, v in enumerate(out)]


def _point_rate(c3d: Any, params: Any, path: Path) -> float:
    rate = _first_number(params, "POINT", "RATE", 0.0)
    if rate <= 0:
        rate = float(c3d["header"]["points"]["frame_rate"])
    if not (rate > 0 and np.isfinite(rate)):
        raise FormatError(path, "no point rate (POINT:RATE and the header rate are 0)")
    return rate


def _analog_metadata(c3d: Any, params: Any) -> dict[str, Any]:
    analogs = np.asarray(c3d["data"]["analogs"], dtype=np.float64)
    if analogs.ndim != 3 or analogs.shape[1] == 0:
        return {}
    n = analogs.shape[1]
    return {
        "analogs": analogs[0].copy(),
        "analog_rate": _first_number(params, "ANALOG", "RATE", float(c3d["header"]["analogs"]["frame_rate"])),
        "analog_labels": _fit(_strings(params, "ANALOG", "LABELS"), n, None),
        "analog_units": _fit(_strings(params, "ANALOG", "UNITS"), n, ""),
        "analog_descriptions": _fit(_strings(params, "ANALOG", "DESCRIPTIONS"), n, ""),
    }


# ----------------------------------------------------------------------------------------------- writing


def write_c3d(motion: MarkerMotion, path: str | os.PathLike[str], force: bool = False) -> None:
    """Write a :class:`MarkerMotion` as a C3D file, atomically.

    A motion read from a C3D file (its :class:`~mocapz.model.c3d_extras.C3DExtras` in
    ``metadata["c3d"]``, for the same frames and markers) is written back in its own storage: the header
    and every parameter as read, the markers from ``motion.positions`` (int16 at the file's scale or
    float32, in its processor's layout), the residual words, model outputs and analogs as read; read
    and written unchanged, the file comes back byte for byte.

    Any other motion is written as a float C3D through ezc3d: points as float32 in ``motion.units``; a
    sample with any non-finite coordinate is written as missing (coordinates 0, residual -1). Analog
    channels in ``motion.metadata`` are written back when their sample count matches the frame count;
    otherwise they are dropped with a warning. An existing ``path`` is kept unless ``force``.
    """
    path = Path(path)
    extras = motion.metadata.get("c3d")
    if isinstance(extras, C3DExtras) and extras.matches(motion.n_frames, motion.n_markers):
        _check_writable(motion, path)
        data = c3d_bytes(motion.positions, extras)
        atomic_write(path, lambda tmp: tmp.write_bytes(data), force=force)
        return
    c3d = _build(motion, path)
    atomic_write(path, lambda tmp: _ezc3d_write(c3d, tmp, path), force=force)


def _build(motion: MarkerMotion, path: Path) -> Any:
    import ezc3d

    _check_writable(motion, path)
    missing = motion.missing
    pts = np.ones((4, motion.n_markers, motion.n_frames), dtype=np.float64)
    pts[:3] = np.where(missing[:, :, None], 0.0, motion.positions).transpose(2, 1, 0)
    c3d = ezc3d.c3d()
    point = c3d["parameters"]["POINT"]
    point["RATE"]["value"] = [float(motion.frame_rate)]
    point["LABELS"]["value"] = [str(s) for s in motion.labels]
    point["UNITS"]["value"] = [motion.units]
    point["SCALE"]["value"] = [-abs(_metadata_scale(motion))]
    descriptions = motion.metadata.get("point_descriptions")
    if isinstance(descriptions, list) and len(descriptions) == motion.n_markers:
        point["DESCRIPTIONS"]["value"] = [str(s) for s in descriptions]
    c3d["data"]["points"] = pts
    c3d["data"]["meta_points"] = {"residuals": _residuals(motion, missing).T[None].copy()}
    c3d["header"]["points"]["first_frame"] = _first_frame(motion) - 1
    _set_analogs(c3d, motion, path)
    return c3d


def _check_writable(motion: MarkerMotion, path: Path) -> None:
    if motion.n_frames == 0:
        raise FormatError(path, "cannot write a C3D without frames")
    if motion.n_frames > MAX_FRAMES:
        raise FormatError(path, f"{motion.n_frames} frames: ezc3d writes the C3D frame count in 16 bits "
                                f"(at most {MAX_FRAMES} frames); split the clip or write TRC")
    if motion.n_markers == 0:
        raise FormatError(path, "cannot write a C3D without markers")
    if not (motion.frame_rate > 0 and np.isfinite(motion.frame_rate)):
        raise FormatError(path, f"frame rate must be positive, got {motion.frame_rate}")
    present = motion.positions[~motion.missing]
    if present.size and np.abs(present).max() > FLOAT32_MAX:
        raise FormatError(path, "marker coordinates too large for C3D float32 storage")
    bad = [s for s in motion.labels if not str(s).isascii()]
    if bad:
        raise FormatError(path, f"C3D labels must be ASCII, got {bad[0]!r}")


def _first_frame(motion: MarkerMotion) -> int:
    """1-based number of the first frame, if the 16-bit C3D header can hold it (else 1)."""
    try:
        first = int(motion.metadata.get("first_frame", 1))
    except (TypeError, ValueError):
        return 1
    return first if 1 <= first <= MAX_FRAMES else 1


def _metadata_scale(motion: MarkerMotion) -> float:
    scale = motion.metadata.get("point_scale", -1.0)
    try:
        scale = float(scale)
    except (TypeError, ValueError):
        return -1.0
    return scale if np.isfinite(scale) and scale != 0 else -1.0


def _residuals(motion: MarkerMotion, missing: np.ndarray) -> np.ndarray:
    """``(frames, markers)`` residuals: the source's where it had them, 0 for other present samples."""
    res = motion.metadata.get("residuals")
    out = np.zeros(missing.shape, dtype=np.float64)
    if isinstance(res, np.ndarray) and res.shape == missing.shape:
        out = np.where(res >= 0, res, 0.0)
    out[missing] = -1.0
    return out


def _set_analogs(c3d: Any, motion: MarkerMotion, path: Path) -> None:
    meta = motion.metadata
    analogs = meta.get("analogs")
    if not isinstance(analogs, np.ndarray) or analogs.ndim != 2 or analogs.shape[0] == 0:
        return
    rate = float(meta.get("analog_rate", 0.0))
    per_frame = rate / motion.frame_rate if rate > 0 else 0.0
    if per_frame < 1 or abs(per_frame - round(per_frame)) > 1e-9 or \
            analogs.shape[1] != round(per_frame) * motion.n_frames:
        warnings.warn(f"{path}: analog channels ({analogs.shape[1]} samples at {rate} Hz) do not match "
                      f"{motion.n_frames} frames at {motion.frame_rate} Hz; not written", stacklevel=4)
        return
    n = analogs.shape[0]
    group = c3d["parameters"]["ANALOG"]
    group["RATE"]["value"] = [rate]
    group["LABELS"]["value"] = [str(s) for s in _fit(list(meta.get("analog_labels", [])), n, None)]
    group["UNITS"]["value"] = [str(s) for s in _fit(list(meta.get("analog_units", [])), n, "")]
    group["DESCRIPTIONS"]["value"] = [str(s) for s in _fit(list(meta.get("analog_descriptions", [])), n, "")]
    c3d["data"]["analogs"] = np.asarray(analogs, dtype=np.float64)[None].copy()


def _ezc3d_write(c3d: Any, tmp: Path, final: Path) -> None:
    """Write through ezc3d to ``tmp`` (ezc3d appends ``.c3d`` to any path not ending in ``.c3d``)."""
    target = tmp.with_name(tmp.name + ".c3d")
    try:
        c3d.write(str(target))
        os.replace(target, tmp)
    except OSError as exc:
        raise MocapzError(f"{final}: could not write C3D ({_short(exc)})") from None
    except Exception as exc:  # ezc3d's own checks raise ValueError/TypeError/RuntimeError
        raise FormatError(final, f"ezc3d could not write this motion ({_short(exc)})") from None
    finally:
        target.unlink(missing_ok=True)
