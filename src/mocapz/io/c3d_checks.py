"""Pre-checks of a C3D file's raw header and parameter section, before ``ezc3d`` is given the file.

ezc3d segfaults on some corrupt parameter sections, silently reads a truncated file as a shorter clip
and raises bare C++ errors on garbage. :func:`check_c3d_file` reads the 512-byte header and the
parameter section itself and checks the header key and processor type, every parameter record, the
parameters ezc3d indexes blindly and the data size against the file size; any problem becomes a
:class:`FormatError`. Sizes are in bytes, positions in 512-byte blocks (1-based, as in the file).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mocapz.errors import FormatError

C3D_KEY = 0x50  # second byte of every C3D file
BLOCK = 512
PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC (little-endian words), MIPS (big-endian)
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
