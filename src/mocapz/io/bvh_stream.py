"""BVH text read and written as a stream: the header first, then frame rows as they come (a capture written to
a pipe), so that a stream encoder can code blocks before the last frame exists.

:func:`read_head` reads up to the ``Frame Time:`` line and gives a 0-frame :class:`Motion` with the clip's
layout; :func:`rows` yields ``(n, channels)`` arrays of the rows read so far, ``chunk`` rows at a time (the
``Frames:`` count of a live capture is not known: it is not checked). :func:`write_rows` is the writing side.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO, TextIO

import numpy as np

from mocapz.errors import FormatError
from mocapz.io.bvh import parse_bvh_head
from mocapz.io.common import common_decimals, format_rows, snap_rate
from mocapz.model.motion import Motion

MAX_HEAD_LINES = 100_000


def read_head(stream: BinaryIO, name: str) -> tuple[Motion, int]:
    """The clip's layout (a 0-frame motion, decimals unknown) and the number of lines read."""
    lines: list[str] = []
    while True:
        raw = stream.readline()
        if not raw:
            raise FormatError(name, "no 'Frame Time:' line: the BVH header ends early (truncated input?)", len(lines))
        lines.append(raw.decode("utf-8", errors="replace").rstrip("\r\n"))
        if lines[-1].strip().lower().startswith("frame time"):
            break
        if len(lines) > MAX_HEAD_LINES:
            raise FormatError(name, f"no 'Frame Time:' line in the first {MAX_HEAD_LINES} lines")
    skeleton, frame_time = parse_bvh_head(lines, Path(name))
    motion = Motion(skeleton=skeleton, channels=np.zeros((0, skeleton.n_channels)),
                    frame_rate=snap_rate(1.0 / frame_time), name=Path(name).stem, source_format="bvh",
                    metadata={"frame_time": frame_time})
    return motion, len(lines)


def rows(stream: BinaryIO, n_channels: int, name: str, first_line: int, chunk: int = 1) -> Iterator[np.ndarray]:
    """Frame rows ``(k, channels)`` as they are read, ``k <= chunk`` (FormatError naming the line of a bad row)."""
    batch: list[np.ndarray] = []
    line = first_line
    for raw in stream:
        line += 1
        text = raw.decode("utf-8", errors="replace")
        if not text.strip():
            continue
        try:
            row = np.array(text.split(), dtype=np.float64)
        except ValueError:
            raise FormatError(name, "non-numeric value in a frame row", line) from None
        if row.size != n_channels:
            raise FormatError(name, f"a frame row has {row.size} values, the hierarchy declares {n_channels} "
                                    "channels", line)
        if not np.isfinite(row).all():
            raise FormatError(name, "non-finite value (NaN/inf) in a frame row", line)
        batch.append(row)
        if len(batch) >= chunk:
            yield np.stack(batch)
            batch = []
    if batch:
        yield np.stack(batch)


def with_decimals(template: Motion, first_rows: np.ndarray) -> Motion:
    """The template with the decimals its first rows are written with (later rows with more are exceptions
    of the lossless codec: still exact)."""
    from dataclasses import replace

    return replace(template, decimals=common_decimals(first_rows) if first_rows.size else None)


def write_rows(out: TextIO, values: np.ndarray, decimals: object) -> None:
    """Frame rows ``(frames, channels)`` as BVH text."""
    if len(values):
        if not np.isfinite(values).all():
            raise FormatError(None, "refusing to write non-finite channel values")
        out.write(format_rows(values, decimals))
