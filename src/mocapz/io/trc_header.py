"""TRC header: the five header lines parsed into a :class:`TRCHeader`, and written back for a MarkerMotion.

The header lines are (tab-separated)::

    PathFileType  4  (X/Y/Z)  gait.trc
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
    100.00    100.00      487        33          mm     100.00        1                   487
    Frame#  Time  R.Shoulder  <tab> <tab>  R.Offset ...
            X1 Y1 Z1 X2 ...

``DataRate`` is in Hz, ``Units`` the unit of the coordinates (``mm`` when absent). The data rows that
follow are :mod:`mocapz.io.trc`'s job.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from mocapz.errors import FormatError
from mocapz.model.motion import MarkerMotion

HEADER_LINES = 5
STANDARD_KEYS = ("DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units", "OrigDataRate",
                 "OrigDataStartFrame", "OrigNumFrames")


@dataclass
class TRCHeader:
    """The five header lines of a TRC file.

    ``names`` has one entry per named marker slot (``""`` for a slot left empty), ``data_start`` is the
    0-based index of the first line after the header (and after a blank separator line, if any).
    """

    path_fields: list[str]
    fields: dict[str, str]
    rate: float
    n_frames: int
    n_markers: int
    units: str
    names: list[str]
    data_start: int


# ----------------------------------------------------------------------------------------------- reading


def parse_header(lines: list[str], path: Path) -> TRCHeader:
    """Parse the five header lines (1-based line numbers in errors)."""
    if not lines or not lines[0].lstrip("\ufeff").startswith("PathFileType"):
        raise FormatError(path, "not a TRC file (the first line does not start with PathFileType)", 1)
    if len(lines) < HEADER_LINES:
        raise FormatError(path, f"truncated header: a TRC header has {HEADER_LINES} lines, "
                                f"found {len(lines)}", len(lines))
    fields = _header_fields(lines, path)
    _check_coordinate_row(lines[4], path)
    data_start = HEADER_LINES
    while data_start < len(lines) and not lines[data_start].strip():
        data_start += 1
    return TRCHeader(
        path_fields=[f.strip() for f in lines[0].split("\t")[1:] if f.strip()],
        fields=fields,
        rate=_header_number(fields, "DataRate", path, positive=True),
        n_frames=int(_header_number(fields, "NumFrames", path, integer=True)),
        n_markers=int(_header_number(fields, "NumMarkers", path, integer=True)),
        units=fields.get("Units", "") or "mm",
        names=_marker_names(lines[3], path),
        data_start=data_start,
    )


def _header_fields(lines: list[str], path: Path) -> dict[str, str]:
    keys = _trim_fields(lines[1].split("\t"))
    values = _trim_fields(lines[2].split("\t"))
    if len(keys) != len(values):
        raise FormatError(path, f"header has {len(keys)} keywords (line 2) but {len(values)} values", 3)
    fields = dict(zip(keys, values, strict=True))
    for key in ("DataRate", "NumFrames", "NumMarkers"):
        if key not in fields:
            raise FormatError(path, f"header keyword {key} missing", 2)
    return fields


def _trim_fields(fields: list[str]) -> list[str]:
    out = [f.strip() for f in fields]
    while out and not out[-1]:
        out.pop()
    return out


def _header_number(fields: dict[str, str], key: str, path: Path, positive: bool = False,
                   integer: bool = False) -> float:
    text = fields[key]
    try:
        value = float(text)
    except ValueError:
        raise FormatError(path, f"header {key} is not a number: {text!r}", 3) from None
    if not math.isfinite(value) or value < 0 or (positive and value == 0):
        raise FormatError(path, f"header {key} must be {'positive' if positive else 'non-negative'}, "
                                f"got {text!r}", 3)
    if integer and value != int(value):
        raise FormatError(path, f"header {key} must be a whole number, got {text!r}", 3)
    return value


def _marker_names(line: str, path: Path) -> list[str]:
    """Names of the marker slots of the name row (``""`` for an empty slot), trailing empties cut.

    A name normally sits on every third field (``name<tab><tab><tab>``); a row that is not aligned so
    is read as the plain list of its non-empty fields.
    """
    fields = [f.strip() for f in line.split("\t")]
    if not fields[0].lower().startswith("frame"):
        raise FormatError(path, f"expected the marker name row 'Frame#<tab>Time<tab>...', "
                                f"found {line.strip()[:40]!r}", 4)
    slots = fields[2:]
    if any(f for i, f in enumerate(slots) if i % 3):
        return [f for f in slots if f]
    return _trim_fields(slots[::3])


def _check_coordinate_row(line: str, path: Path) -> None:
    tokens = line.split()
    if tokens and not tokens[0].upper().startswith("X"):
        raise FormatError(path, f"expected the coordinate row 'X1<tab>Y1<tab>Z1...', "
                                f"found {line.strip()[:40]!r}", 5)


def orig_start_frame(head: TRCHeader) -> int:
    """The header's OrigDataStartFrame (1 if absent or not a number)."""
    try:
        return int(float(head.fields.get("OrigDataStartFrame", "1")))
    except ValueError:
        return 1


# ----------------------------------------------------------------------------------------------- writing


def header_text(motion: MarkerMotion, path: Path) -> str:
    """The five header lines describing ``motion`` (and the blank separator line the source had), ``\n`` ends."""
    meta = motion.metadata
    path_fields = meta.get("trc_path_fields") or ["4", "(X/Y/Z)", path.name]
    fields = _header_values(motion)
    m = motion.n_markers
    lines = [
        "\t".join(["PathFileType", *map(str, path_fields)]),
        "\t".join(fields),
        "\t".join(fields.values()),
        "Frame#\tTime\t" + "".join(f"{label}\t\t\t" for label in motion.labels),
        "\t\t" + "".join(f"X{i}\tY{i}\tZ{i}\t" for i in range(1, m + 1)),
    ]
    if meta.get("trc_blank_line", True):
        lines.append("")
    return "\n".join(lines) + "\n"


def _header_values(motion: MarkerMotion) -> dict[str, str]:
    """Header keyword -> value text: the source's fields, updated to describe ``motion``."""
    raw = motion.metadata.get("trc_header")
    raw = {str(k): str(v) for k, v in raw.items()} if isinstance(raw, dict) else {}
    rate = _same_number(raw.get("DataRate"), motion.frame_rate) or _format_rate(motion.frame_rate)
    fresh = {
        "DataRate": rate,
        "CameraRate": raw.get("CameraRate", rate),
        "NumFrames": _same_number(raw.get("NumFrames"), motion.n_frames) or str(motion.n_frames),
        "NumMarkers": _same_number(raw.get("NumMarkers"), motion.n_markers) or str(motion.n_markers),
        "Units": motion.units,
        "OrigDataRate": raw.get("OrigDataRate", rate),
        "OrigDataStartFrame": raw.get("OrigDataStartFrame", str(first_frame(motion))),
        "OrigNumFrames": raw.get("OrigNumFrames", str(motion.n_frames)),
    }
    out = {key: raw[key] for key in raw}
    out.update(fresh)
    return {key: out[key] for key in [*raw, *(k for k in STANDARD_KEYS if k not in raw)]}


def _same_number(text: str | None, value: float) -> str | None:
    """``text`` if it already spells ``value`` (keeps the source's padding and decimals)."""
    try:
        return text if text is not None and float(text) == value else None
    except ValueError:
        return None


def _format_rate(rate: float) -> str:
    return f"{rate:.2f}" if round(rate, 2) == rate else repr(float(rate))


def first_frame(motion: MarkerMotion) -> int:
    """1-based number of the motion's first frame (``metadata["first_frame"]``, else 1)."""
    try:
        return int(motion.metadata.get("first_frame", 1))
    except (TypeError, ValueError):
        return 1
