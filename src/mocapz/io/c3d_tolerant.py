"""C3D files that ezc3d cannot read, decoded by mocapz from the raw bytes.

Two kinds of file come here (:func:`mocapz.io.c3d.read_c3d` decides):

* files ezc3d must not be given (:attr:`~mocapz.io.c3d_checks.C3DLayout.ezc3d_unsafe`): SGI/MIPS
  (big-endian) storage, which ezc3d refuses (c3d.org sample01 ``Eb015si.c3d``, ``Eb015sr.c3d``), and a
  POINT:FRAMES that runs past the end of the file while the header's frame count fills it exactly;
* files ezc3d refuses although :func:`~mocapz.io.c3d_checks.check_c3d_file` accepts their structure.
  c3d.org sample13 ``Dance.c3d`` (PhoeniX) is both: POINT:DATA_START is 0, POINT:DESCRIPTIONS and
  ANALOG:DESCRIPTIONS have length 0, ANALOG:OFFSET is stored as float (ezc3d: "OFFSET parameter is not
  an INT"), FORCE_PLATFORMS:USED is missing, and POINT:FRAMES says 500 where the header and the data
  hold 499 frames.

What is recovered, and how. Everything is sized by the checked :class:`~mocapz.io.c3d_checks.C3DLayout`,
so nothing is read outside the file and no allocation is larger than the file:

* the data start is the header's block (never POINT:DATA_START); the frame count, point count, analog
  channels and samples per frame are those the checks measured against the file size;
* points: ``(x, y, z, residual word)`` per point and frame, int16 times ``|POINT:SCALE|`` (the header's
  scale when the parameter is absent; the i-th value for point i when there is one per point) or float32,
  in the processor's byte order (DEC floats converted); the residual is read as ezc3d reads it (the
  fourth value as an integer word: -1 when negative, a missing point, else its high byte times
  ``|scale|``);
* analogs: ``(value - |ANALOG:OFFSET|) * ANALOG:SCALE * ANALOG:GEN_SCALE`` per channel as ezc3d computes
  it, whatever numeric type OFFSET is stored as;
* parameters: every numeric parameter as its values, every char parameter as its strings (a length-0
  parameter gives empty strings); groups and parameters missing from the file are simply absent.

The result has the shape of an ezc3d ``c3d`` object (``header``, ``parameters``, ``data``), so that
:mod:`mocapz.io.c3d` builds the :class:`~mocapz.model.motion.MarkerMotion` the same way for both readers;
on the Intel and DEC files ezc3d reads, it gives ezc3d's values exactly.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mocapz.errors import FormatError
from mocapz.io.c3d_checks import PROCESSORS, C3DLayout, C3DParam, decode_float32


def read_c3d_raw(path: Path, layout: C3DLayout) -> dict[str, Any]:
    """Decode a checked C3D file into ezc3d's layout.

    Returns ``{"header": ..., "parameters": {GROUP: {NAME: {"value": ...}}}, "data": ...}`` with
    ``data["points"]`` ``(4, points, frames)`` float64 (the last row 1; NaN where missing),
    ``data["meta_points"]["residuals"]`` ``(1, points, frames)``, ``data["analogs"]``
    ``(1, channels, frames * samples)`` float64, and the 0-based header ``first_frame`` / ``last_frame``.
    """
    h = layout.header
    values = _values(_raw(path, layout), layout)  # (frames, values per frame), float64
    words = layout.frames, layout.points, 4
    points = values[:, :4 * layout.points].reshape(words)
    scale = point_scales(layout)
    xyz = points[:, :, :3] if h.is_float else points[:, :, :3] * scale[None, :, None]
    residuals = _residuals(points[:, :, 3], scale)
    xyz = np.where((residuals < 0)[:, :, None], np.nan, xyz)
    out = np.ones((4, layout.points, layout.frames))
    out[:3] = xyz.transpose(2, 1, 0)
    first = h.first_frame - 1
    return {
        "header": {"points": {"first_frame": first, "last_frame": first + layout.frames - 1,
                              "frame_rate": h.rate, "size": layout.points},
                   "analogs": {"frame_rate": h.rate * layout.samples, "size": layout.channels}},
        "parameters": _parameters(layout),
        "data": {"points": out, "meta_points": {"residuals": residuals.T[None].copy()},
                 "analogs": _analogs(values[:, 4 * layout.points:], layout)[None]},
    }


def _raw(path: Path, layout: C3DLayout) -> bytes:
    """The bytes of the data section the layout declares (checked to lie inside the file)."""
    n = layout.frames * layout.frame_values * layout.value_bytes
    try:
        with path.open("rb") as fh:
            fh.seek(layout.data_offset)
            raw = fh.read(n)
    except OSError as exc:
        raise FormatError(path, f"could not read the C3D data ({exc.strerror or exc})") from None
    if len(raw) != n:
        raise FormatError(path, f"truncated: {len(raw)} bytes of data where the file declares {n}")
    return raw


def _values(raw: bytes, layout: C3DLayout) -> np.ndarray:
    """Every stored value, ``(frames, frame_values)`` float64 (int16 or float32 in the file)."""
    if layout.header.is_float:
        flat = decode_float32(raw, layout.header.processor)
    else:
        flat = np.frombuffer(raw, dtype=f"{PROCESSORS[layout.header.processor]}i2").astype(np.float64)
    return flat.reshape(layout.frames, layout.frame_values)


def _residuals(fourth: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Residuals ``(frames, points)`` from the fourth value of every point ``(frames, points)``, as ezc3d
    reads them: the value as an integer word, -1 when negative (a missing point), else its high byte
    (the low byte holds the camera mask) times the point's ``|scale|``."""
    word = np.trunc(fourth)
    return np.where(word < 0, -1.0, np.floor(word / 256) * scale[None, :])


def _numbers(layout: C3DLayout, group: str, *names: str) -> np.ndarray:
    """The values of ``GROUP:NAME`` and its ``NAME2``, ``NAME3``... continuations, float64."""
    out = []
    for name in names:
        for key in [name] + [f"{name}{i}" for i in range(2, 100)]:
            param = layout.params.get((group, key))
            if param is None:
                break
            out.append(param.numbers(layout.header.processor))
    return np.concatenate(out) if out else np.empty(0)


def point_scales(layout: C3DLayout) -> np.ndarray:
    """``|scale|`` of every point, ``(points,)``: POINT:SCALE's value for the point if it has one for
    each, else its first value, else the header's scale (as ezc3d); float64 of the stored float32."""
    values = np.abs(_numbers(layout, "POINT", "SCALE"))
    if values.size == 0:
        values = np.array([abs(layout.header.scale)])
    scales = np.full(layout.points, values[0])
    n = min(values.size, layout.points)
    scales[:n] = values[:n]
    return scales


def _analogs(values: np.ndarray, layout: C3DLayout) -> np.ndarray:
    """Analog channels ``(channels, frames * samples)`` from the per-frame analog values
    ``(frames, samples * channels)``: ``(value - |offset|) * scale * gen_scale``, the subtraction in
    float32 as ezc3d does it. The checks made sure SCALE and OFFSET have a value for every channel."""
    n = layout.channels
    if n == 0:
        return np.zeros((0, layout.frames * layout.samples))
    samples = values.reshape(-1, n).T.astype(np.float32)  # (channels, frames * samples)
    offsets = np.abs(np.trunc(_numbers(layout, "ANALOG", "OFFSET")[:n])).astype(np.float32)
    scales = _numbers(layout, "ANALOG", "SCALE")[:n]
    gen = _numbers(layout, "ANALOG", "GEN_SCALE")
    gen_scale = float(gen[0]) if gen.size else 1.0
    return (samples - offsets[:, None]).astype(np.float64) * scales[:, None] * gen_scale


def _parameters(layout: C3DLayout) -> dict[str, dict[str, dict[str, Any]]]:
    """``{GROUP: {NAME: {"value": ...}}}``: strings for char parameters, float64 values for the others."""
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for (group, name), param in layout.params.items():
        out.setdefault(group, {})[name] = {"value": _value(param, layout.header.processor)}
    return out


def _value(param: C3DParam, processor: int) -> list[str] | np.ndarray:
    return param.strings() if param.kind == -1 else param.numbers(processor)
