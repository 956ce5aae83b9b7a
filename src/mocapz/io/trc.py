"""TRC (Motion Analysis "track row column") marker files: tab-separated text, parsed with numpy.

Layout::

    PathFileType  4  (X/Y/Z)  gait.trc
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
    100.00    100.00      487        33          mm     100.00        1                   487
    Frame#  Time  R.Shoulder  <tab> <tab>  R.Offset ...
            X1 Y1 Z1 X2 ...
    (optional blank line)
    1  0.000  x1 y1 z1 x2 ...         an empty field is a missing coordinate

Rows may stop early (trailing missing markers left out). Markers are the name-row slots; data columns
beyond the named ones (written by some exporters) are kept as markers named ``*<column>``, never
dropped. The reader is strict where the file contradicts itself: NumFrames must equal the number of
data rows, NumMarkers must lie between the number of names and the number of marker columns, every
field must be a number, and a sample must have all of X, Y, Z or none.

The five header lines are parsed and written by :mod:`mocapz.io.trc_header`; this module reads and writes
the data rows: positions ``(frames, markers, 3)`` in the header's ``Units``, NaN for a missing sample.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.errors import FormatError
from mocapz.io.common import (
    atomic_write,
    common_decimals,
    detect_decimals,
    exception_budget,
    fits_decimals,
    read_text,
)
from mocapz.io.trc_header import HEADER_LINES, TRCHeader, first_frame, header_text, orig_start_frame, parse_header
from mocapz.model.motion import MarkerMotion

_SPACED_TAB = re.compile(r" *\t *")


# ----------------------------------------------------------------------------------------------- reading


def read_trc(path: str | os.PathLike[str]) -> MarkerMotion:
    """Read a TRC file into a :class:`MarkerMotion`.

    Returns:
        positions ``(frames, markers, 3)`` float64 in the file's ``Units``, NaN for missing samples;
        ``decimals`` the number of decimals the coordinates were written with (``None`` if over 9);
        ``metadata`` holds ``first_frame``, the ``trc_frame_numbers`` and ``trc_times`` (seconds)
        columns and the header fields needed to write the file back in the same layout.
    """
    path = Path(path)
    text = read_text(path)
    lines = text.splitlines()
    head = parse_header(lines, path)
    rows, line_numbers = _data_rows(lines, head.data_start)
    _check_frame_count(head, line_numbers, len(lines), path)
    table = parse_table(rows, line_numbers, path)
    n_markers = _marker_count(head, table.shape[1], path)
    labels, unnamed = _labels(head.names, n_markers)
    positions = _positions(table, n_markers, labels, line_numbers, path)
    frames, times = _index_columns(table, line_numbers, path)
    return MarkerMotion(
        labels=labels,
        positions=positions,
        frame_rate=head.rate,
        units=head.units,
        name=path.stem,
        source_format="trc",
        decimals=_decimals(positions),
        metadata=_metadata(path, text, lines, head, frames, times, unnamed),
    )


def _data_rows(lines: list[str], start: int) -> tuple[list[str], np.ndarray]:
    """Non-blank data lines (trailing whitespace and tabs cut) and their 1-based line numbers."""
    rows: list[str] = []
    numbers: list[int] = []
    for i in range(start, len(lines)):
        row = lines[i].rstrip()
        if row:
            rows.append(row)
            numbers.append(i + 1)
    return rows, np.array(numbers, dtype=np.int64)


def _check_frame_count(head: TRCHeader, line_numbers: np.ndarray, n_lines: int, path: Path) -> None:
    n_rows = len(line_numbers)
    if n_rows < head.n_frames:
        raise FormatError(path, f"truncated: header NumFrames is {head.n_frames} but only {n_rows} "
                                f"data rows follow", n_lines)
    if n_rows > head.n_frames:
        raise FormatError(path, f"header NumFrames is {head.n_frames} but {n_rows} data rows follow "
                                f"(first extra row)", int(line_numbers[head.n_frames]))


def parse_table(rows: list[str], line_numbers: np.ndarray, path: Path) -> np.ndarray:
    """Parse tab-separated numeric rows into a ``(rows, max fields)`` float64 array, NaN-padded.

    An empty field becomes NaN. The text is converted in one numpy call (no per-value Python loop).
    """
    if not rows:
        return np.empty((0, 2))
    counts = np.fromiter((row.count("\t") + 1 for row in rows), dtype=np.int64, count=len(rows))
    text = "\n".join(rows)
    if " " in text:
        text = _SPACED_TAB.sub("\t", text)
    text = "\n" + text
    if "\n\t" in text:  # empty first field
        text = text.replace("\n\t", "\nnan\t")
    for _ in range(2):  # two passes fill runs of empty fields ("\t\t\t" -> "\tnan\tnan\t")
        if "\t\t" in text:
            text = text.replace("\t\t", "\tnan\t")
    try:
        values = np.fromstring(text, dtype=np.float64, sep=" ")
    except ValueError:
        values = None
    if values is None or values.size != counts.sum():
        _raise_bad_field(rows, line_numbers, path)
    table = np.full((len(rows), int(counts.max())), np.nan)
    starts = np.cumsum(counts) - counts
    row_index = np.repeat(np.arange(len(rows)), counts)
    table[row_index, np.arange(values.size) - np.repeat(starts, counts)] = values
    return table


def _raise_bad_field(rows: list[str], line_numbers: np.ndarray, path: Path) -> None:
    """Find the first field that is not a number (slow path, only on error)."""
    for r, row in enumerate(rows):
        for c, field in enumerate(row.split("\t")):
            text = field.strip()
            try:
                if text:
                    float(text)
                    if len(text.split()) > 1:
                        raise ValueError
            except ValueError:
                raise FormatError(path, f"non-numeric value {text[:30]!r} in {_column_name(c)} of "
                                        f"data row {r + 1}", int(line_numbers[r])) from None
    raise FormatError(path, "unreadable data rows", int(line_numbers[0]) if len(line_numbers) else None)


def _column_name(col: int) -> str:
    if col < 2:
        return ("Frame#", "Time")[col]
    return f"{'XYZ'[(col - 2) % 3]}{(col - 2) // 3 + 1}"


def _marker_count(head: TRCHeader, width: int, path: Path) -> int:
    """Markers = max(named slots, data columns / 3); NumMarkers must lie between names and that."""
    named = len(head.names)
    in_data = max(math.ceil((width - 2) / 3), 0)
    n = max(named, in_data)
    if head.n_markers < named:
        raise FormatError(path, f"header NumMarkers is {head.n_markers} but the name row names "
                                f"{named} markers", 3)
    if head.n_markers > n:
        raise FormatError(path, f"header NumMarkers is {head.n_markers} but the file has at most {n} "
                                f"marker columns ({named} names, {in_data} in the data rows)", 3)
    return n


def _labels(names: list[str], n: int) -> tuple[list[str], list[int]]:
    """One label per marker; an unnamed slot gets ``*<column number>`` (made unique)."""
    labels = [names[i] if i < len(names) else "" for i in range(n)]
    unnamed = [i for i, name in enumerate(labels) if not name]
    taken = set(labels)
    for i in unnamed:
        label = f"*{i + 1}"
        while label in taken:
            label += "'"
        labels[i] = label
        taken.add(label)
    return labels, unnamed


def _positions(table: np.ndarray, n: int, labels: list[str], line_numbers: np.ndarray,
               path: Path) -> np.ndarray:
    """``(frames, n, 3)`` coordinates; a sample must have all of X, Y, Z or none."""
    coords = np.full((table.shape[0], 3 * n), np.nan)
    width = min(table.shape[1] - 2, 3 * n)
    if width > 0:
        coords[:, :width] = table[:, 2:2 + width]
    positions = coords.reshape(table.shape[0], n, 3)
    if np.isinf(positions).any():
        row = int(np.argwhere(np.isinf(positions))[0][0])
        raise FormatError(path, f"infinite coordinate in data row {row + 1}", int(line_numbers[row]))
    present = np.isfinite(positions).sum(axis=2)
    partial = np.argwhere((present != 0) & (present != 3))
    if partial.size:
        row, marker = (int(v) for v in partial[0])
        raise FormatError(path, f"marker {labels[marker]!r} has only some of X/Y/Z in data row {row + 1}",
                          int(line_numbers[row]))
    return positions


def _index_columns(table: np.ndarray, line_numbers: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The Frame# and Time columns; both must be present on every row."""
    for col, what in ((0, "frame number"), (1, "time")):
        bad = np.flatnonzero(~np.isfinite(table[:, col]))
        if bad.size:
            raise FormatError(path, f"missing or bad {what} in data row {bad[0] + 1}",
                              int(line_numbers[bad[0]]))
    frames = table[:, 0]
    if np.array_equal(frames, np.round(frames)):
        frames = frames.astype(np.int64)
    return frames, table[:, 1].copy()


def _decimals(positions: np.ndarray) -> int | None:
    values = positions[np.isfinite(positions)]
    if not values.size:
        return None
    dec = common_decimals(values[:, None])
    return None if dec is None else int(dec[0])


def _metadata(path: Path, text: str, lines: list[str], head: TRCHeader, frames: np.ndarray,
              times: np.ndarray, unnamed: list[int]) -> dict[str, Any]:
    first_row = lines[head.data_start] if head.data_start < len(lines) else ""
    meta: dict[str, Any] = {
        "path": str(path),
        "file_bytes": path.stat().st_size,
        "first_frame": int(frames[0]) if frames.size else orig_start_frame(head),
        "trc_frame_numbers": frames,
        "trc_times": times,
        "trc_time_decimals": _time_decimals(times, first_row),
        "trc_path_fields": head.path_fields,
        "trc_header": dict(head.fields),
        "trc_num_markers_declared": head.n_markers,
        "trc_unnamed": unnamed,
        "trc_newline": "\r\n" if "\r\n" in text[:4096] else "\n",
        "trc_blank_line": head.data_start > HEADER_LINES,
        "trc_trailing_tab": first_row.rstrip("\r\n ").endswith("\t"),
    }
    if "Units" not in head.fields or not head.fields["Units"]:
        meta["units_note"] = "no Units in the header; millimetres assumed"
    return meta


def _time_decimals(times: np.ndarray, first_row: str) -> int | None:
    """Decimals of the Time column: enough for every value, and at least as many as the first row shows
    (``0.000`` keeps three decimals)."""
    dec = detect_decimals(times[:, None]) if times.size else None
    if dec is None:
        return None
    fields = first_row.split("\t")
    shown = fields[1].strip().partition(".")[2] if len(fields) > 1 else ""
    return max(int(dec[0]), len(shown) if shown.isdigit() else 0)


# ----------------------------------------------------------------------------------------------- writing


def write_trc(motion: MarkerMotion, path: str | os.PathLike[str], force: bool = False) -> None:
    """Write a :class:`MarkerMotion` as TRC text, atomically.

    Coordinates are written with ``motion.decimals`` decimals when known, else as the shortest text that
    reads back to the same float64; a missing sample (any non-finite coordinate) is written as three
    empty fields. Frame numbers, times and header fields read from a TRC (``metadata``) are reused when
    they still fit the motion; NumFrames, NumMarkers, DataRate and Units always describe the motion.
    """
    path = Path(path)
    _check_writable(motion, path)
    text = header_text(motion, path) + _data_text(motion)
    newline = motion.metadata.get("trc_newline", "\n")
    if newline == "\r\n":
        text = text.replace("\n", "\r\n")
    data = text.encode("utf-8")
    atomic_write(path, lambda tmp: tmp.write_bytes(data), force=force)


def _check_writable(motion: MarkerMotion, path: Path) -> None:
    if not (motion.frame_rate > 0 and math.isfinite(motion.frame_rate)):
        raise FormatError(path, f"frame rate must be positive, got {motion.frame_rate}")
    for label in [*motion.labels, motion.units]:
        if any(c in str(label) for c in "\t\r\n"):
            raise FormatError(path, f"a TRC label or unit cannot hold tabs or line breaks: {label!r}")


def _data_text(motion: MarkerMotion) -> str:
    """The data rows: Frame#, Time, then X/Y/Z per marker (empty fields for missing samples)."""
    n = motion.n_frames
    if n == 0:
        return ""
    frames, frame_fmt = _frame_column(motion)
    times, time_fmt = _time_column(motion)
    table = np.empty((n, 2 + 3 * motion.n_markers))
    table[:, 0], table[:, 1] = frames, times
    positions = np.where(motion.missing[:, :, None], np.nan, motion.positions)
    table[:, 2:] = positions.reshape(n, -1)
    value_fmt = "%r" if motion.decimals is None else f"%.{int(motion.decimals)}f"
    tail = "\t" if motion.metadata.get("trc_trailing_tab", False) else ""
    fmts = [frame_fmt, time_fmt] + [value_fmt] * (3 * motion.n_markers)
    fmt = "\t".join(fmts) + tail
    lines = [fmt % tuple(row) for row in table.tolist()]
    if motion.decimals is not None:  # the few values off the common decimals: written to read back exactly
        values = table[:, 2:]
        off = ~fits_decimals(values, np.full(values.shape[1], int(motion.decimals))) & np.isfinite(values)
        if off.sum() <= exception_budget(int(np.isfinite(values).sum())):
            for r in np.flatnonzero(off.any(axis=1)).tolist():
                row = [repr(v) if c >= 2 and off[r, c - 2] else f % v
                       for c, (f, v) in enumerate(zip(fmts, table[r].tolist(), strict=True))]
                lines[r] = "\t".join(row).replace("nan", "") + tail
    return "\n".join(lines).replace("nan", "") + "\n"


def _frame_column(motion: MarkerMotion) -> tuple[np.ndarray, str]:
    frames = motion.metadata.get("trc_frame_numbers")
    if not (isinstance(frames, np.ndarray) and frames.shape == (motion.n_frames,)
            and np.isfinite(frames).all()):
        frames = first_frame(motion) + np.arange(motion.n_frames)
    frames = np.asarray(frames, dtype=np.float64)
    return frames, "%d" if np.array_equal(frames, np.round(frames)) else "%r"


def _time_column(motion: MarkerMotion) -> tuple[np.ndarray, str]:
    times = motion.metadata.get("trc_times")
    if isinstance(times, np.ndarray) and times.shape == (motion.n_frames,) and np.isfinite(times).all():
        dec = motion.metadata.get("trc_time_decimals")
        return times.astype(np.float64), "%r" if dec is None else f"%.{int(dec)}f"
    step = 1.0 / motion.frame_rate
    dec = next((d for d in range(3, 7) if abs(round(step, d) - step) < 1e-12), 6)
    return np.arange(motion.n_frames) * step, f"%.{dec}f"
