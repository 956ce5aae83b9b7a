"""C3D files that ezc3d cannot read, read by the pure-Python ``c3d`` package (``c3d.Reader``).

:func:`mocapz.io.c3d.read_c3d` comes here for the files ezc3d must not be given
(:attr:`~mocapz.io.c3d_checks.C3DLayout.ezc3d_unsafe`: SGI/MIPS storage, which ezc3d refuses, as in
c3d.org sample01 ``Eb015si.c3d`` / ``Eb015sr.c3d``; a POINT:FRAMES that runs past the end of the file)
and for those ezc3d refuses although :func:`~mocapz.io.c3d_checks.check_c3d_file` accepts their
structure (c3d.org sample13 ``Dance.c3d``: ezc3d says "OFFSET parameter is not an INT").

:func:`read_c3d_package` gives the result the shape of an ezc3d ``c3d`` object (``header``,
``parameters``, ``data``), so that :mod:`mocapz.io.c3d` builds the motion's metadata the same way for
both readers (the marker positions and everything kept for writing come from
:mod:`mocapz.io.c3d_raw`, whichever reader read the file). How the package is used:

* it is given the file's bytes with the parameter-section block count (byte 3 of the section, a size
  hint, see :mod:`mocapz.io.c3d_checks`) set to the blocks before the data: the package stops at the
  declared count and would lose the groups past it (``Dance.c3d`` declares 3 blocks and fills 6, its
  ANALOG group lies past the third);
* its frames must have the geometry the checks measured against the file (points, analog values per
  frame, integer or float words); only the checked frames are read, so a POINT:FRAMES past the end of
  the file reads the frames the file holds;
* analogs are ``(value - ANALOG:OFFSET) * ANALOG:SCALE * ANALOG:GEN_SCALE`` as the package computes them.
  The package reads OFFSET's bytes as int16 words and fails on an OFFSET stored as float (``Dance.c3d``):
  such an OFFSET is given to it as int16 words of its values rounded toward 0, and a fractional part is
  added back to the analogs; ``parameters`` holds the float values the file stores;
* every warning it raises is caught (none reaches the user) and any error it raises becomes a
  :class:`~mocapz.errors.FormatError` naming the file.
"""

from __future__ import annotations

import io
import itertools
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.errors import FormatError
from mocapz.io.c3d_checks import BLOCK, PROCESSORS, C3DLayout


def read_c3d_package(path: Path, layout: C3DLayout) -> dict[str, Any]:
    """Read a checked C3D file with ``c3d.Reader`` into ezc3d's layout.

    Returns ``{"header": ..., "parameters": {GROUP: {NAME: {"value": ...}}}, "data": ...}`` with
    ``data["points"]`` ``(4, points, frames)`` float64 (the last row 1; NaN where the package marks a
    sample invalid), ``data["meta_points"]["residuals"]`` ``(1, points, frames)`` (the package's),
    ``data["analogs"]`` ``(1, channels, frames * samples)`` float64, and the 0-based header
    ``first_frame`` / ``last_frame``. Raises :class:`FormatError` if the package cannot read the file.
    """
    import c3d

    if not hasattr(c3d, "Reader"):  # a c3d.py on sys.path (a script's folder, the working directory)
        raise FormatError(path, f"the c3d package is shadowed by {getattr(c3d, '__file__', c3d)}")
    data = _with_full_parameter_space(_file_bytes(path), layout)
    try:
        with warnings.catch_warnings(record=True):
            warnings.simplefilter("always")  # recorded and dropped: none may reach the user
            reader = c3d.Reader(io.BytesIO(data))
            _check_geometry(reader, layout, path)
            params = parameters(reader)
            float_offset = _int16_offsets(reader, layout)
            frames = list(itertools.islice(reader.read_frames(copy=True), layout.frames))
            result = _result(reader, layout, frames, params, float_offset)
    except FormatError:
        raise
    except Exception as exc:  # AssertionError, ValueError, struct.error... from the package
        raise FormatError(path, f"c3d: {_message(exc)}") from None
    if len(frames) < layout.frames:
        raise FormatError(path, f"truncated: c3d read {len(frames)} of {layout.frames} frames")
    return result


def _file_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise FormatError(path, f"could not read the file ({exc.strerror or exc})") from None


def _message(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return " ".join(text[0].split()) if text else type(exc).__name__


def _with_full_parameter_space(data: bytes, layout: C3DLayout) -> bytes:
    """``data`` with the parameter section's block count set to every block before the data (at most 255),
    where the checks found the records: the package reads no record past the declared count."""
    h = layout.header
    at = (h.param_block - 1) * BLOCK + 2
    blocks = min(h.data_start - h.param_block, 255)
    if blocks <= data[at]:
        return data
    return data[:at] + bytes([blocks]) + data[at + 1:]


def _check_geometry(reader: Any, layout: C3DLayout, path: Path) -> None:
    """The package must read frames of the size the checks measured, else its values are not the file's."""
    is_float = reader.point_scale < 0
    theirs = (int(reader.point_used), int(reader.analog_used) * int(reader.analog_per_frame), bool(is_float))
    ours = (layout.points, layout.channels * layout.samples, layout.header.is_float)
    if int(reader.header.data_block) != layout.header.data_start or theirs != ours:
        raise FormatError(path, f"c3d reads {theirs[0]} points, {theirs[1]} analog values a frame "
                                f"({'float' if is_float else 'integer'} storage) where the file holds "
                                f"{ours[0]} points, {ours[1]} analog values "
                                f"({'float' if ours[2] else 'integer'} storage)")


def _int16_offsets(reader: Any, layout: C3DLayout) -> np.ndarray | None:
    """An ANALOG:OFFSET stored as float (the package reads OFFSET as int16 words and fails on the float's
    bytes) is replaced in the reader by int16 words of its values rounded toward 0; returns the float
    values (``None`` when OFFSET is not float), from which :func:`_analogs` corrects the analogs."""
    group, param = reader.get("ANALOG"), reader.get("ANALOG:OFFSET")
    if layout.channels == 0 or param is None or param.bytes_per_element != 4 or not param.dimensions:
        return None
    values = np.asarray(param.float_array, dtype=np.float64).ravel()
    words = np.clip(np.trunc(np.nan_to_num(values)), -32768, 32767).astype(f"{PROCESSORS[layout.header.processor]}i2")
    group.remove_param("OFFSET")
    group.add_param("OFFSET", desc=param.desc, bytes_per_element=2, dimensions=[values.size], bytes=words.tobytes())
    return values[:layout.channels]


def _result(reader: Any, layout: C3DLayout, frames: list[tuple[int, np.ndarray, Any]],
            params: dict[str, dict[str, dict[str, Any]]], float_offset: np.ndarray | None) -> dict[str, Any]:
    n = len(frames)
    pts = np.array([p for _, p, _ in frames], dtype=np.float64).reshape(n, layout.points, 5)
    invalid = pts[:, :, 3] < 0
    out = np.ones((4, layout.points, n))
    out[:3] = np.where(invalid[:, :, None], np.nan, pts[:, :, :3]).transpose(2, 1, 0)
    first = int(reader.header.first_frame) - 1
    return {
        "header": {"points": {"first_frame": first, "last_frame": first + n - 1,
                              "frame_rate": float(reader.header.frame_rate), "size": layout.points},
                   "analogs": {"frame_rate": float(reader.analog_rate), "size": layout.channels}},
        "parameters": params,
        "data": {"points": out, "meta_points": {"residuals": pts[:, :, 3].T[None].copy()},
                 "analogs": _analogs(reader, layout, frames, float_offset)[None]},
    }


def _analogs(reader: Any, layout: C3DLayout, frames: list[tuple[int, np.ndarray, Any]],
             float_offset: np.ndarray | None) -> np.ndarray:
    """``(channels, frames * samples)`` float64: each frame's ``(channels, samples)`` block side by side."""
    if layout.channels == 0 or layout.samples == 0 or not frames:
        return np.zeros((layout.channels, len(frames) * layout.samples))
    values = np.concatenate([np.asarray(a, dtype=np.float64) for _, _, a in frames], axis=1)
    if float_offset is not None:  # (value - int16 offset) * k + (int16 offset - float offset) * k: 0 if integral
        gen_scale, scales, int16_offset = reader.get_analog_transform_parameters()
        k = np.asarray(scales, dtype=np.float64) * float(gen_scale)
        values = values + ((np.asarray(int16_offset, dtype=np.float64) - float_offset) * k)[:, None]
    return values


def parameters(reader: Any) -> dict[str, dict[str, dict[str, Any]]]:
    """``{GROUP: {NAME: {"value": ...}}}`` of a ``c3d.Reader``: the strings of a char parameter (trailing
    blanks removed, in file order), the float64 values of a numeric one (int8, int16 or float32)."""
    dec = reader.proc_type == "DEC"
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for group_name, group in reader.group_items():
        for name, param in group.param_items():
            out.setdefault(group_name.strip(), {})[name.strip()] = {"value": _value(param, dec)}
    return out


def _value(param: Any, dec: bool) -> list[str] | np.ndarray:
    if param.bytes_per_element == -1:
        if not param.dimensions:
            return []
        if len(param.dimensions) == 1:
            return [param.string_value.rstrip()]
        return [str(s).rstrip() for s in np.asarray(param.string_array, dtype=object).ravel()]
    if param.num_elements == 0:
        return np.empty(0)
    if param.bytes_per_element == 4 and dec:
        # the package's array conversion: its scalar one (float_value) reads a DEC 0 as -2**127
        from c3d.c3d import DEC_to_IEEE_BYTES

        return np.asarray(DEC_to_IEEE_BYTES(param.bytes), dtype=np.float64)
    kind = {1: "int8", 2: "int16", 4: "float32"}[param.bytes_per_element]
    if not param.dimensions:
        value = param.float_value if kind == "float32" else getattr(param, f"{kind}_value")
        return np.array([value], dtype=np.float64)
    return np.asarray(getattr(param, f"{kind}_array"), dtype=np.float64).ravel()
