"""C3D marker files, read and written through ``ezc3d``.

Reading keeps the 3D points (``POINT:LABELS``, ``POINT:RATE``, ``POINT:UNITS``, first frame), turns
missing samples (ezc3d NaN or a negative residual) into NaN, and keeps the analog channels, their
labels, units and rate, the point residuals and descriptions in ``MarkerMotion.metadata`` so that
:func:`write_c3d` puts them back. Other parameter groups (events, force platforms, subjects) are not
carried over.

Before ezc3d sees a file its 512-byte header is checked here (key byte, processor type, parameter
section and data size against the file size): ezc3d silently reads a truncated file as a shorter
clip, and raises bare C++ errors on garbage; both become :class:`FormatError`.
"""

from __future__ import annotations

import os
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FormatError, MocapzError
from ..motion import MarkerMotion
from .common import atomic_write

C3D_KEY = 0x50  # second byte of every C3D file
BLOCK = 512
PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC (little-endian words), MIPS (big-endian)
FLOAT32_MAX = float(np.finfo(np.float32).max)


@dataclass(frozen=True)
class C3DHeader:
    """The fields of the 512-byte C3D header that size the file.

    ``first_frame`` / ``last_frame`` are the header's 1-based 16-bit frame numbers (a clip longer than
    65535 frames stores the true count in its parameters only, so ``frames`` is then a lower bound).
    """

    param_block: int
    param_blocks: int
    processor: int
    points: int
    analog_per_frame: int
    first_frame: int
    last_frame: int
    is_float: bool
    data_start: int

    @property
    def frames(self) -> int:
        return max(self.last_frame - self.first_frame + 1, 0)

    @property
    def frame_bytes(self) -> int:
        """Bytes of one frame of point + analog data."""
        return (4 * self.points + self.analog_per_frame) * (4 if self.is_float else 2)


# ----------------------------------------------------------------------------------------------- reading


def read_c3d(path: str | os.PathLike[str]) -> MarkerMotion:
    """Read a C3D file into a :class:`MarkerMotion`.

    Returns:
        positions ``(frames, markers, 3)`` float64 in ``POINT:UNITS`` (float32 values for float C3D
        files), NaN where a sample is missing; ``metadata`` holds ``first_frame`` (1-based),
        ``residuals`` ``(frames, markers)``, ``point_scale``, ``point_descriptions`` and, when the file
        has analog channels, ``analogs`` ``(channels, samples)`` float64 with ``analog_labels``,
        ``analog_units``, ``analog_descriptions`` and ``analog_rate`` (Hz).
    """
    path = Path(path)
    header = check_c3d_file(path)
    c3d = _load(path)
    points = np.asarray(c3d["data"]["points"], dtype=np.float64)
    residuals = np.asarray(c3d["data"]["meta_points"]["residuals"], dtype=np.float64)[0].T.copy()
    _check_frame_count(c3d, header, points.shape[2], path)
    positions = points[:3].transpose(2, 1, 0).copy()  # (3, markers, frames) -> (frames, markers, 3)
    missing = (residuals < 0) | ~np.isfinite(positions).all(axis=2)
    positions[missing] = np.nan
    residuals[missing] = -1.0
    params = c3d["parameters"]
    n_markers = positions.shape[1]
    units = _first_string(params, "POINT", "UNITS")
    metadata: dict[str, Any] = {
        "path": str(path),
        "file_bytes": path.stat().st_size,
        "first_frame": int(c3d["header"]["points"]["first_frame"]) + 1,
        "residuals": residuals,
        "point_scale": _first_number(params, "POINT", "SCALE", -1.0),
        "point_descriptions": _fit(_strings(params, "POINT", "DESCRIPTIONS"), n_markers, ""),
        "c3d_float": header.is_float,
        "c3d_processor": header.processor,
    }
    if units is None:
        metadata["units_note"] = "POINT:UNITS missing; millimetres assumed (the C3D default)"
    metadata.update(_analog_metadata(c3d, params))
    return MarkerMotion(
        labels=_fit(_strings(params, "POINT", "LABELS"), n_markers, None),
        positions=positions,
        frame_rate=_point_rate(c3d, params, path),
        units=units or "mm",
        name=path.stem,
        source_format="c3d",
        decimals=None,
        metadata=metadata,
    )


def check_c3d_file(path: Path) -> C3DHeader:
    """Validate a C3D file's header against its size; raise :class:`FormatError` if it cannot be read."""
    if not path.exists():
        raise FormatError(path, "no such file")
    if path.is_dir():
        raise FormatError(path, "is a folder, not a file")
    size = path.stat().st_size
    if size == 0:
        raise FormatError(path, "file is empty")
    with path.open("rb") as fh:
        head = fh.read(BLOCK)
        if len(head) < BLOCK:
            raise FormatError(path, f"too short for a C3D file ({size} bytes; the header alone is {BLOCK})")
        if head[1] != C3D_KEY:
            raise FormatError(path, f"not a C3D file (byte 2 is 0x{head[1]:02x}, a C3D has 0x50 there)")
        param_block = head[0]
        if param_block < 2 or param_block * BLOCK > size:
            raise FormatError(path, f"truncated or corrupt: parameter section at block {param_block} "
                                    f"is outside the file ({size} bytes)")
        fh.seek((param_block - 1) * BLOCK)
        param_head = fh.read(4)
    header = _parse_header(head, param_head, path)
    _check_sizes(header, size, path)
    return header


def _parse_header(head: bytes, param_head: bytes, path: Path) -> C3DHeader:
    processor = param_head[3]
    if processor not in PROCESSORS:
        raise FormatError(path, f"corrupt C3D: unknown processor type {processor} (expected 84, 85 or 86)")
    endian = PROCESSORS[processor]
    words = struct.unpack(f"{endian}9H", head[2:20])
    return C3DHeader(
        param_block=head[0],
        param_blocks=param_head[2],
        processor=processor,
        points=words[0],
        analog_per_frame=words[1],
        first_frame=words[2],
        last_frame=words[3],
        is_float=_scale_is_negative(head[12:16], processor),
        data_start=words[7],
    )


def _scale_is_negative(raw: bytes, processor: int) -> bool:
    """Sign of the header's POINT scale factor (negative = float data) in the file's float layout."""
    if processor == 86:  # big-endian IEEE
        return bool(raw[0] & 0x80)
    if processor == 85:  # DEC: the sign is the top bit of the first little-endian 16-bit word
        return bool(raw[1] & 0x80)
    return bool(raw[3] & 0x80)


def _check_sizes(h: C3DHeader, size: int, path: Path) -> None:
    param_end = (h.param_block - 1 + h.param_blocks) * BLOCK
    if h.param_blocks == 0 or param_end > size:
        raise FormatError(path, f"truncated or corrupt: the parameter section ({h.param_blocks} blocks "
                                f"from block {h.param_block}) does not fit in the file ({size} bytes)")
    if h.data_start < h.param_block + h.param_blocks:
        raise FormatError(path, f"corrupt C3D: data start block {h.data_start} lies inside the "
                                f"parameter section (blocks {h.param_block}-{h.param_block + h.param_blocks - 1})")
    need = (h.data_start - 1) * BLOCK + h.frames * h.frame_bytes
    if need > size:
        raise FormatError(path, f"truncated: the header declares {h.frames} frames of {h.points} points "
                                f"({need} bytes needed) but the file has {size} bytes")


def _load(path: Path) -> Any:
    import ezc3d

    try:
        return ezc3d.c3d(str(path), extract_forceplat_data=False)
    except Exception as exc:  # ezc3d raises RuntimeError, OSError, ValueError... from C++
        raise FormatError(path, f"not a readable C3D file (ezc3d: {_short(exc)})") from None


def _short(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return (text[0] if text else type(exc).__name__).removesuffix(": iostream error")


def _check_frame_count(c3d: Any, header: C3DHeader, frames: int, path: Path) -> None:
    info = c3d["header"]["points"]
    declared = int(info["last_frame"]) - int(info["first_frame"]) + 1
    if frames < max(declared, header.frames):
        raise FormatError(path, f"truncated: {frames} frames of point data where the file declares "
                                f"{max(declared, header.frames)}")


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
    """``n`` entries: ``values`` cut or padded (``fill=None`` pads with ``*<index>`` names)."""
    out = list(values[:n])
    for i in range(len(out), n):
        out.append(f"*{i + 1}" if fill is None else fill)
    return out


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
    """Write a :class:`MarkerMotion` as a float C3D through ezc3d, atomically.

    Points are stored as float32 in ``motion.units``; a sample with any non-finite coordinate is written
    as missing (coordinates 0, residual -1). Analog channels in ``motion.metadata`` (as
    :func:`read_c3d` stores them) are written back when their sample count matches the frame count;
    otherwise they are dropped with a warning. An existing ``path`` is kept unless ``force``.
    """
    path = Path(path)
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
    c3d["header"]["points"]["first_frame"] = max(int(motion.metadata.get("first_frame", 1)) - 1, 0)
    _set_analogs(c3d, motion, path)
    return c3d


def _check_writable(motion: MarkerMotion, path: Path) -> None:
    if motion.n_frames == 0:
        raise FormatError(path, "cannot write a C3D without frames")
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
