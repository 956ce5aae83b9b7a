"""Pre-checks of a C3D file's raw header and parameter section, before ``ezc3d`` is given the file.

ezc3d segfaults on some corrupt parameter sections, silently reads a truncated file as a shorter clip
and raises bare C++ errors on garbage. :func:`check_c3d_file` reads the 512-byte header and the
parameter section itself and checks the header key and processor type, every parameter record, the
parameters ezc3d indexes blindly and the data size against the file size; any problem becomes a
:class:`FormatError`. It returns a :class:`C3DLayout` (the header, the parameters and the checked data
size), which also says when ezc3d must not be given the file at all (SGI/MIPS storage, which ezc3d
refuses; a POINT:FRAMES that runs past the end of the file) so that the ``c3d`` package
(:mod:`mocapz.io.c3d_pure`) reads it instead. Sizes are in bytes, positions in 512-byte blocks (1-based,
as in the file).

The checks refuse only what would crash or hang a reader or what no reader can read as the file
declares it: a parameter record that does not fit in its space, char parameters of length 0 declaring
more strings than the section has bytes (ezc3d and the c3d package loop over each), parameters ezc3d
indexes blindly left empty, data past the end of the file. Header inconsistencies readers survive
(c3d.org ``FP1.C3D``: more parameter blocks filled than declared; ``Dance.c3d``: POINT:DATA_START 0, a
float ANALOG:OFFSET, POINT:FRAMES one past the data) are left to the readers.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from mocapz.errors import FormatError

C3D_KEY = 0x50  # second byte of every C3D file
MAX_EMPTY_FRAMES = 65535  # most frames a file without points and analogs may declare (the header's 16 bits)
BLOCK = 512
PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC (little-endian words), MIPS (big-endian)
# Parameters ezc3d reads as ``values[0]`` without checking that they hold a value.
SCALAR_PARAMS = [("POINT", n) for n in ("USED", "FRAMES", "RATE", "SCALE", "DATA_START")] + [
    ("ANALOG", n) for n in ("USED", "RATE", "GEN_SCALE")]


@dataclass(frozen=True)
class C3DHeader:
    """The fields of the 512-byte C3D header (and of the parameter-section header) that size the file.

    ``first_frame`` / ``last_frame`` are the header's 1-based 16-bit frame numbers; ``rate`` is in Hz;
    ``scale`` is the header's point scale (negative for float storage).
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
    scale: float

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
            return decode_float32(self.data, processor)
        if self.kind in (1, 2):
            fmt = f"{PROCESSORS[processor]}{len(self.data) // self.kind}{'b' if self.kind == 1 else 'h'}"
            return np.array(struct.unpack(fmt, self.data), dtype=np.float64)
        return np.empty(0)

    def strings(self) -> list[str]:
        """A char parameter's ``count`` strings of ``dims[0]`` characters each, trailing blanks removed
        (all empty when the length is 0); ``[]`` for a numeric parameter."""
        if self.kind != -1:
            return []
        width = self.dims[0]
        text = self.data.decode("latin-1")
        return [text[i * width:(i + 1) * width].rstrip() for i in range(self.count)]


@dataclass(frozen=True)
class C3DLayout:
    """What :func:`check_c3d_file` found: the header, every parameter keyed ``(GROUP, NAME)``, and the data
    as checked against the file size: ``frames`` frames of ``points`` points and ``channels`` analog
    channels sampled ``samples`` times a frame, from byte ``data_offset`` on. ``ezc3d_unsafe`` says why
    ezc3d must not be given the file (``""`` when it may).
    """

    header: C3DHeader
    params: dict[tuple[str, str], C3DParam]
    points: int
    frames: int
    channels: int
    samples: int
    ezc3d_unsafe: str = ""

    @property
    def value_bytes(self) -> int:
        """Bytes of one stored value: 4 (float32) or 2 (int16)."""
        return 4 if self.header.is_float else 2

    @property
    def frame_values(self) -> int:
        """Values stored for one frame: x, y, z and residual word per point, then the analog samples."""
        return 4 * self.points + self.channels * self.samples

    @property
    def data_offset(self) -> int:
        return (self.header.data_start - 1) * BLOCK


def check_c3d_file(path: Path) -> C3DLayout:
    """Validate a C3D file before ezc3d reads it; raise :class:`FormatError` if it cannot be read.

    Checks the header key and processor type, walks every parameter record (each must fit in its
    space, lengths ezc3d reads as signed bytes must be < 128), checks the parameters ezc3d indexes
    without bounds checks, and checks the file size against the data the parameters declare.
    """
    size = _file_size(path)
    header, section = _read_sections(path, size)
    params = _walk_parameters(section, header.processor, path)
    _check_parameters(params, header.processor, path)
    return _data_layout(header, params, size, path)


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


def _read_sections(path: Path, size: int) -> tuple[C3DHeader, bytes]:
    """The parsed header and the parameter space: every block from the parameter block to the data start.

    The block count in the parameter-section header (its byte 3) must fit in the file, but it is only a
    size hint: some writers fill more blocks than they declare (c3d.org sample15 ``FP1.C3D``, from Peak
    Performance, declares 3 blocks and its ``ANALOG:UNITS`` record crosses into block 4, its records
    end in block 6, before the data at block 7). Readers (ezc3d included) follow the records to the
    last one, so the records may use the whole space before the data; each must still fit in it.
    """
    with path.open("rb") as fh:
        head = fh.read(BLOCK)
        if head[1] != C3D_KEY:
            raise FormatError(path, f"not a C3D file (byte 2 is 0x{head[1]:02x}, a C3D has 0x50 there)")
        start = (head[0] - 1) * BLOCK
        if head[0] < 2 or start + 4 > size:
            raise FormatError(path, f"truncated or corrupt: the parameter section (block {head[0]}) "
                                    f"is outside the file ({size} bytes)")
        fh.seek(start)
        header = _parse_header(head, fh.read(4), path)
        if header.param_blocks == 0 or start + header.param_blocks * BLOCK > size:
            raise FormatError(path, f"truncated or corrupt: the parameter section ({header.param_blocks} "
                                    f"blocks from block {head[0]}) does not fit in the file ({size} bytes)")
        fh.seek(start)
        return header, fh.read(min((header.data_start - header.param_block) * BLOCK, size - start))


def _parse_header(head: bytes, intro: bytes, path: Path) -> C3DHeader:
    """The 512-byte header ``head`` and the 4-byte parameter-section header ``intro`` (block count,
    processor type)."""
    processor = intro[3]
    if processor not in PROCESSORS:
        raise FormatError(path, f"corrupt C3D: unknown processor type {processor} (expected 84, 85 or 86)")
    words = struct.unpack(f"{PROCESSORS[processor]}9H", head[2:20])
    header = C3DHeader(
        param_block=head[0],
        param_blocks=intro[2],
        processor=processor,
        points=words[0],
        first_frame=words[2],
        last_frame=words[3],
        is_float=_float32(head[12:16], processor) < 0,
        data_start=words[7],
        analog_samples=words[8],
        rate=_float32(head[20:24], processor),
        scale=_float32(head[12:16], processor),
    )
    if header.data_start < header.param_block + header.param_blocks:
        raise FormatError(path, f"corrupt C3D: data start block {header.data_start} lies inside the "
                                f"parameter section (blocks {header.param_block}-"
                                f"{header.param_block + header.param_blocks - 1})")
    return header


def decode_float32(raw: bytes, processor: int) -> np.ndarray:
    """4-byte floats in the file's layout, ``(len(raw) // 4,)`` float32 values as float64: IEEE
    little-endian (Intel, 84), big-endian (SGI/MIPS, 86) or DEC (85: 16-bit words swapped, exponent 2
    higher; a zero exponent byte gives 0), as ezc3d decodes them. Signalling NaNs become quiet NaNs."""
    b = np.frombuffer(raw, dtype=np.uint8, count=len(raw) // 4 * 4).reshape(-1, 4)
    if processor == 85:
        b = b[:, [2, 3, 0, 1]]  # a copy
        b[:, 3] = np.where(b[:, 3] > 0, b[:, 3] - 1, 0)
    with np.errstate(invalid="ignore"):  # widening a signalling NaN sets the invalid flag
        return np.ascontiguousarray(b).view(">f4" if processor == 86 else "<f4").ravel().astype(np.float64)


def _float32(raw: bytes, processor: int) -> float:
    """One 4-byte float in the file's layout (Intel / DEC / MIPS), as ezc3d decodes it."""
    return float(decode_float32(raw, processor)[0])


def _walk_parameters(section: bytes, processor: int, path: Path) -> dict[tuple[str, str], C3DParam]:
    """All parameter records, keyed ``(GROUP, NAME)``; each record must lie inside its space.

    ezc3d trusts the record lengths and dimensions and crashes (segfault) on a corrupt record.
    """
    pos, groups, raw = 4, {}, []
    while True:
        if pos + 2 > len(section):
            raise FormatError(path, "corrupt C3D: the parameter records run into the data or past the end of the file")
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
        if body.count > len(section):  # strings of length 0: readers loop over (or allocate) each one
            raise FormatError(path, f"corrupt C3D: parameter {name!r} declares {body.count} strings of "
                                    f"length 0 in a {len(section)}-byte parameter section")
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


def _data_layout(h: C3DHeader, params: dict[tuple[str, str], C3DParam], size: int, path: Path) -> C3DLayout:
    """The data the parameters declare (as ezc3d sizes it) must fit in the file.

    One exception: when POINT:FRAMES runs past the end of the file but the header's frame count ends
    exactly where the file does (within the padding of the last block), the header is right and
    POINT:FRAMES wrong (c3d.org sample13 ``Dance.c3d``: 500 declared, 499 stored and in the header);
    that count is kept and ezc3d, which would read past the end of the file, is not given the file.
    """
    points = _param_int(params, ("POINT", "USED"), h.points, h.processor, path)
    frames = _frame_count(h, params)
    channels = _param_int(params, ("ANALOG", "USED"), 0, h.processor, path)
    samples = _analog_samples(h, params, path)
    if points > 65535 or channels > 65535:
        raise FormatError(path, f"corrupt C3D: {points} points / {channels} analog channels declared")
    layout = C3DLayout(h, params, points, frames, channels, samples,
                       "SGI/MIPS storage, which ezc3d does not read" if h.processor == 86 else "")
    if layout.frame_values == 0 and frames > MAX_EMPTY_FRAMES:  # no data to measure the count against
        raise FormatError(path, f"corrupt C3D: {frames} frames declared with no point and no analog channel "
                                f"(readers would loop over them)")
    end = layout.data_offset + frames * layout.frame_values * layout.value_bytes
    if end <= size:
        return layout
    header_end = layout.data_offset + h.frames * layout.frame_values * layout.value_bytes
    if 0 < h.frames < frames and 0 <= size - header_end < BLOCK:
        return replace(layout, frames=h.frames, ezc3d_unsafe=f"POINT:FRAMES ({frames}) runs past the end of "
                                                             f"the file, the header's {h.frames} frames fill it")
    raise FormatError(path, f"truncated: the file declares {frames} frames of {points} points and "
                            f"{channels} analog channels ({end} bytes) but has {size} bytes")


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
