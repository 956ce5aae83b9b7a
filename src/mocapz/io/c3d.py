"""C3D marker files, read and written through ``ezc3d``.

Reading keeps the 3D points (``POINT:LABELS``, ``POINT:RATE``, ``POINT:UNITS``, first frame), turns
missing samples (ezc3d NaN or a negative residual) into NaN, and keeps the analog channels, their
labels, units and rate, the point residuals and descriptions in ``MarkerMotion.metadata`` so that
:func:`write_c3d` puts them back. Other parameter groups (events, force platforms, subjects) are not
carried over.

Before ezc3d sees a file it is checked here (header key and processor type, every parameter record,
the parameters ezc3d indexes blindly, the data size against the file size): ezc3d segfaults on some
corrupt parameter sections, silently reads a truncated file as a shorter clip and raises bare C++
errors on garbage; all of these become :class:`FormatError`.
"""

from __future__ import annotations

import os
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.errors import FormatError, MocapzError
from mocapz.io.common import atomic_write
from mocapz.model.motion import MarkerMotion

C3D_KEY = 0x50  # second byte of every C3D file
BLOCK = 512
PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC (little-endian words), MIPS (big-endian)
FLOAT32_MAX = float(np.finfo(np.float32).max)
MAX_FRAMES = 65535  # ezc3d writes POINT:FRAMES and the header frame numbers as 16-bit integers
# Parameters ezc3d reads as ``values[0]`` without checking that they hold a value.
SCALAR_PARAMS = [("POINT", n) for n in ("USED", "FRAMES", "RATE", "SCALE", "DATA_START")] + [
    ("ANALOG", n) for n in ("USED", "RATE", "GEN_SCALE")]


@dataclass(frozen=True)
class C3DHeader:
    """The fields of the 512-byte C3D header (and of the parameter-section header) that size the file.

    ``first_frame`` / ``last_frame`` are the header's 1-based 16-bit frame numbers; ``rate`` is in Hz.
    """

    param_block: int
    param_blocks: int
    processor: int
    points: int
    first_frame: int
    last_frame: int
    is_float: bool
    data_start: int
    analog_samples: int
    rate: float

    @property
    def frames(self) -> int:
        return max(self.last_frame - self.first_frame + 1, 0)


@dataclass(frozen=True)
class C3DParam:
    """One parameter record: ``kind`` -1 char, 1 int8, 2 int16, 4 float32; raw ``data`` bytes."""

    kind: int
    dims: tuple[int, ...]
    data: bytes

    @property
    def count(self) -> int:
        """Number of values (of strings for a char parameter, whose first dimension is the length)."""
        dims = self.dims[1:] if self.kind == -1 else self.dims
        return int(np.prod(dims, dtype=np.int64))

    def numbers(self, processor: int) -> np.ndarray:
        """The values as float64 (empty for char parameters)."""
        if self.kind == 4:
            return np.array([_float32(self.data[i:i + 4], processor) for i in range(0, len(self.data), 4)])
        if self.kind in (1, 2):
            fmt = f"{PROCESSORS[processor]}{len(self.data) // self.kind}{'b' if self.kind == 1 else 'h'}"
            return np.array(struct.unpack(fmt, self.data), dtype=np.float64)
        return np.empty(0)


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
    positions, residuals = _point_data(c3d, path)
    params = c3d["parameters"]
    units = _first_string(params, "POINT", "UNITS")
    metadata = _metadata(path, c3d, header, residuals)
    if units is None:
        metadata["units_note"] = "POINT:UNITS missing; millimetres assumed (the C3D default)"
    return MarkerMotion(
        labels=_fit(_strings(params, "POINT", "LABELS"), positions.shape[1], None),
        positions=positions,
        frame_rate=_point_rate(c3d, params, path),
        units=units or "mm",
        name=path.stem,
        source_format="c3d",
        decimals=None,
        metadata=metadata,
    )


def _point_data(c3d: Any, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Positions ``(frames, markers, 3)`` with NaN gaps and residuals ``(frames, markers)`` (-1 = gap)."""
    points = np.asarray(c3d["data"]["points"], dtype=np.float64)
    residuals = np.asarray(c3d["data"]["meta_points"]["residuals"], dtype=np.float64)[0].T.copy()
    _check_frame_count(c3d, points.shape[2], path)
    positions = points[:3].transpose(2, 1, 0).copy()  # (3, markers, frames) -> (frames, markers, 3)
    missing = (residuals < 0) | ~np.isfinite(positions).all(axis=2)
    positions[missing] = np.nan
    residuals[missing] = -1.0
    return positions, residuals


def _metadata(path: Path, c3d: Any, header: C3DHeader, residuals: np.ndarray) -> dict[str, Any]:
    params = c3d["parameters"]
    meta: dict[str, Any] = {
        "path": str(path),
        "file_bytes": path.stat().st_size,
        "first_frame": int(c3d["header"]["points"]["first_frame"]) + 1,
        "residuals": residuals,
        "point_scale": _first_number(params, "POINT", "SCALE", -1.0),
        "point_descriptions": _fit(_strings(params, "POINT", "DESCRIPTIONS"), residuals.shape[1], ""),
        "c3d_float": header.is_float,
        "c3d_processor": header.processor,
    }
    meta.update(_analog_metadata(c3d, params))
    return meta


def check_c3d_file(path: Path) -> C3DHeader:
    """Validate a C3D file before ezc3d reads it; raise :class:`FormatError` if it cannot be read.

    Checks the header key and processor type, walks every parameter record (each must fit in its
    space, lengths ezc3d reads as signed bytes must be < 128), checks the parameters ezc3d indexes
    without bounds checks, and checks the file size against the data the parameters declare.
    """
    size = _file_size(path)
    head, section = _read_sections(path, size)
    header = _parse_header(head, section, path)
    params = _walk_parameters(section, header.processor, path)
    _check_parameters(params, header.processor, path)
    _check_data_size(header, params, size, path)
    return header


def _file_size(path: Path) -> int:
    if not path.exists():
        raise FormatError(path, "no such file")
    if path.is_dir():
        raise FormatError(path, "is a folder, not a file")
    size = path.stat().st_size
    if size == 0:
        raise FormatError(path, "file is empty")
    if size < BLOCK:
        raise FormatError(path, f"too short for a C3D file ({size} bytes; the header alone is {BLOCK})")
    return size


def _read_sections(path: Path, size: int) -> tuple[bytes, bytes]:
    """The 512-byte header and the whole parameter section (as many blocks as it declares)."""
    with path.open("rb") as fh:
        head = fh.read(BLOCK)
        if head[1] != C3D_KEY:
            raise FormatError(path, f"not a C3D file (byte 2 is 0x{head[1]:02x}, a C3D has 0x50 there)")
        start = (head[0] - 1) * BLOCK
        if head[0] < 2 or start + 4 > size:
            raise FormatError(path, f"truncated or corrupt: the parameter section (block {head[0]}) "
                                    f"is outside the file ({size} bytes)")
        fh.seek(start)
        section = fh.read(4)
        blocks = section[2]
        if blocks == 0 or start + blocks * BLOCK > size:
            raise FormatError(path, f"truncated or corrupt: the parameter section ({blocks} blocks from "
                                    f"block {head[0]}) does not fit in the file ({size} bytes)")
        fh.seek(start)
        return head, fh.read(blocks * BLOCK)


def _parse_header(head: bytes, section: bytes, path: Path) -> C3DHeader:
    processor = section[3]
    if processor not in PROCESSORS:
        raise FormatError(path, f"corrupt C3D: unknown processor type {processor} (expected 84, 85 or 86)")
    words = struct.unpack(f"{PROCESSORS[processor]}9H", head[2:20])
    header = C3DHeader(
        param_block=head[0],
        param_blocks=section[2],
        processor=processor,
        points=words[0],
        first_frame=words[2],
        last_frame=words[3],
        is_float=_float32(head[12:16], processor) < 0,
        data_start=words[7],
        analog_samples=words[8],
        rate=_float32(head[20:24], processor),
    )
    if header.data_start < header.param_block + header.param_blocks:
        raise FormatError(path, f"corrupt C3D: data start block {header.data_start} lies inside the "
                                f"parameter section (blocks {header.param_block}-"
                                f"{header.param_block + header.param_blocks - 1})")
    return header


def _float32(raw: bytes, processor: int) -> float:
    """A 4-byte float in the file's layout (Intel / DEC / MIPS), as ezc3d decodes it."""
    if processor == 86:
        return float(struct.unpack(">f", raw)[0])
    if processor == 85:
        raw = bytes([raw[2], raw[3], raw[0], (raw[1] - 1) & 0xFF if raw[1] else 0])
    return float(struct.unpack("<f", raw)[0])


def _walk_parameters(section: bytes, processor: int, path: Path) -> dict[tuple[str, str], C3DParam]:
    """All parameter records, keyed ``(GROUP, NAME)``; each record must lie inside its space.

    ezc3d trusts the record lengths and dimensions and crashes (segfault) on a corrupt record.
    """
    pos, groups, raw = 4, {}, []
    while True:
        if pos + 2 > len(section):
            raise FormatError(path, "corrupt C3D: the parameter section runs past its declared blocks")
        n_chars, gid = struct.unpack("bb", section[pos:pos + 2])
        if n_chars == 0 or gid == 0:
            break
        name_end = pos + 2 + abs(n_chars)
        name = section[pos + 2:name_end].decode("latin-1").strip().upper()
        if name_end + 2 > len(section):
            raise FormatError(path, "corrupt C3D: a parameter record runs past the parameter section")
        (offset,) = struct.unpack(f"{PROCESSORS[processor]}H", section[name_end:name_end + 2])
        stop = name_end + offset if offset else len(section)
        body = _record_body(section, name_end + 2, gid > 0, min(stop, len(section)))
        if body is None:
            raise FormatError(path, f"corrupt C3D: parameter record {name!r} does not fit in its space")
        if gid < 0:
            groups[-gid] = name
        else:
            raw.append((gid, name, body))
        if not offset:
            break
        pos = stop
    return _name_parameters(groups, raw, path)


def _record_body(section: bytes, pos: int, is_param: bool, stop: int) -> C3DParam | None:
    """Decode a record's body (a group's body is just its description); ``None`` if it overruns."""
    param = C3DParam(kind=0, dims=(), data=b"")
    if is_param:
        if pos + 2 > stop:
            return None
        kind, n_dims = struct.unpack("bB", section[pos:pos + 2])
        if kind not in (-1, 1, 2, 4) or n_dims > 7 or pos + 2 + n_dims > stop:
            return None
        if kind == -1 and n_dims == 0:  # ezc3d indexes the first dimension of a char parameter
            return None
        dims = tuple(section[pos + 2:pos + 2 + n_dims])
        n_bytes = abs(kind) * int(np.prod(dims, dtype=np.int64))
        pos += 2 + n_dims
        param = C3DParam(kind=kind, dims=dims, data=section[pos:pos + n_bytes])
        pos += n_bytes
    if pos + 1 > stop or section[pos] > 127:  # ezc3d reads the description length as a signed byte
        return None
    return param if pos + 1 + section[pos] <= stop else None


def _name_parameters(groups: dict[int, str], raw: list[tuple[int, str, C3DParam]],
                     path: Path) -> dict[tuple[str, str], C3DParam]:
    params: dict[tuple[str, str], C3DParam] = {}
    for gid, name, param in raw:
        if gid not in groups:
            raise FormatError(path, f"corrupt C3D: parameter {name!r} belongs to undefined group {gid}")
        params[(groups[gid], name)] = param
    return params


def _check_parameters(params: dict[tuple[str, str], C3DParam], processor: int, path: Path) -> None:
    """The parameters ezc3d reads without bounds checks must hold what they promise."""
    for key in SCALAR_PARAMS:
        if key in params and params[key].count < 1:
            raise FormatError(path, f"corrupt C3D: parameter {':'.join(key)} is empty")
    channels = _param_int(params, ("ANALOG", "USED"), 0, processor, path)
    if channels == 0:
        return
    for name in ("SCALE", "OFFSET"):
        have = sum(p.count for (g, n), p in params.items() if g == "ANALOG" and _is_part(n, name))
        if have < channels:
            raise FormatError(path, f"corrupt C3D: ANALOG:{name} has {have} values for {channels} channels")
    if ("ANALOG", "GEN_SCALE") not in params:
        raise FormatError(path, "corrupt C3D: ANALOG:GEN_SCALE missing")


def _is_part(name: str, base: str) -> bool:
    """``SCALE``, ``SCALE2``, ``SCALE3``... (continuations of a parameter over 255 entries)."""
    return name == base or (name.startswith(base) and name[len(base):].isdigit())


def _param_int(params: dict[tuple[str, str], C3DParam], key: tuple[str, str], default: int,
               processor: int, path: Path) -> int:
    if key not in params:
        return default
    value = params[key].numbers(processor)
    if value.size == 0 or not np.isfinite(value[0]) or not 0 <= value[0] < 2**31:
        raise FormatError(path, f"corrupt C3D: {':'.join(key)} is {value[:1].tolist()}")
    return int(value[0])


def _check_data_size(h: C3DHeader, params: dict[tuple[str, str], C3DParam], size: int, path: Path) -> None:
    """The data the parameters declare (as ezc3d sizes it) must fit in the file."""
    points = _param_int(params, ("POINT", "USED"), h.points, h.processor, path)
    frames = _frame_count(h, params)
    channels = _param_int(params, ("ANALOG", "USED"), 0, h.processor, path)
    samples = _analog_samples(h, params, path)
    if points > 65535 or channels > 65535:
        raise FormatError(path, f"corrupt C3D: {points} points / {channels} analog channels declared")
    frame_bytes = (4 * points + channels * samples) * (4 if h.is_float else 2)
    need = (h.data_start - 1) * BLOCK + frames * frame_bytes
    if need > size:
        raise FormatError(path, f"truncated: the file declares {frames} frames of {points} points and "
                                f"{channels} analog channels ({need} bytes) but has {size} bytes")


def _frame_count(h: C3DHeader, params: dict[tuple[str, str], C3DParam]) -> int:
    """POINT:FRAMES as ezc3d converts it (int16 read unsigned, float for long clips), else the header."""
    param = params.get(("POINT", "FRAMES"))
    frames = 0
    if param is not None and param.count:
        value = float(param.numbers(h.processor)[0])
        if np.isfinite(value) and value > -(2**31):
            frames = int(value) % 65536 if param.kind in (1, 2) else max(int(value), 0)
    return frames or h.frames


def _analog_samples(h: C3DHeader, params: dict[tuple[str, str], C3DParam], path: Path) -> int:
    """Analog samples per point frame: ANALOG:RATE / POINT:RATE as ezc3d computes it, else the header."""
    rates = [params[k].numbers(h.processor)[0] if k in params and params[k].count else np.nan
             for k in (("POINT", "RATE"), ("ANALOG", "RATE"))]
    point_rate, analog_rate = (h.rate if np.isnan(rates[0]) else rates[0]), rates[1]
    if not np.isfinite(point_rate) or int(point_rate) == 0 or np.isnan(analog_rate):
        return h.analog_samples
    samples = analog_rate / point_rate
    if not (np.isfinite(samples) and 0 <= samples <= 65535):
        raise FormatError(path, f"corrupt C3D: analog rate {analog_rate} / point rate {point_rate}")
    return int(samples)


def _load(path: Path) -> Any:
    import ezc3d

    try:
        return ezc3d.c3d(str(path), extract_forceplat_data=False)
    except Exception as exc:  # ezc3d raises RuntimeError, OSError, ValueError... from C++
        raise FormatError(path, f"not a readable C3D file (ezc3d: {_short(exc)})") from None


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
