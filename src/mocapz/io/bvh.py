"""BVH (Biovision hierarchy) reader and writer.

Any rotation order, 3 or 6 (or any subset of) channels on any joint, End Sites, CRLF, tabs and any
number precision. Rotation channels compose in the order listed; position channels replace the OFFSET.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.errors import FormatError
from mocapz.io.common import (
    CMU_UNIT_CM,
    atomic_write,
    common_decimals,
    guess_unit_cm,
    read_text,
    rest_height,
    row_texts,
    snap_rate,
)
from mocapz.model.motion import Motion
from mocapz.model.skeleton import CHANNEL_NAMES, Skeleton

CMU_JOINTS = {"Hips", "LHipJoint", "LeftUpLeg", "LowerBack", "Spine1", "LeftHandIndex1", "RThumb"}


class _Tokens:
    """Whitespace tokens of the HIERARCHY section with their line numbers."""

    def __init__(self, lines: list[str], path: Path, first_line: int = 1) -> None:
        self.items: list[tuple[str, int]] = []
        for i, line in enumerate(lines, start=first_line):
            for tok in line.split():
                self.items.append((tok, i))
        self.pos = 0
        self.path = path
        self.last_line = first_line + len(lines) - 1

    def next(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            raise FormatError(self.path, f"unexpected end of HIERARCHY, expected {what}", self.last_line)
        tok = self.items[self.pos]
        self.pos += 1
        return tok

    def expect(self, word: str) -> int:
        tok, line = self.next(repr(word))
        if tok.upper() != word.upper():
            raise FormatError(self.path, f"expected {word!r}, found {tok!r}", line)
        return line

    def floats(self, n: int, what: str) -> np.ndarray:
        vals = []
        for _ in range(n):
            tok, line = self.next(what)
            try:
                vals.append(float(tok))
            except ValueError:
                raise FormatError(self.path, f"bad number {tok!r} in {what}", line) from None
        return np.array(vals)


def read_bvh(path: str | os.PathLike[str]) -> Motion:
    """Read a BVH file into a :class:`Motion` (values in file units and degrees)."""
    path = Path(path)
    lines = read_text(path).splitlines()  # the text itself not kept beside its lines (a long clip's peak memory)
    motion_line = next((i for i, ln in enumerate(lines) if ln.strip().upper() == "MOTION"), None)
    if not lines or lines[0].strip().upper() != "HIERARCHY":
        raise FormatError(path, "not a BVH file (first line is not HIERARCHY)", 1)
    if motion_line is None:
        raise FormatError(path, "no MOTION section (truncated file?)", len(lines))
    skeleton = _parse_hierarchy(_Tokens(lines[1:motion_line], path, first_line=2), path)
    channels, frame_time = _parse_motion(lines, motion_line, skeleton.n_channels, path)
    _set_units(skeleton)
    return Motion(
        skeleton=skeleton,
        channels=channels,
        frame_rate=snap_rate(1.0 / frame_time),
        name=path.stem,
        source_format="bvh",
        decimals=common_decimals(channels) if channels.size else None,
        metadata={"path": str(path), "file_bytes": path.stat().st_size, "frame_time": frame_time},
    )


def _parse_hierarchy(tok: _Tokens, path: Path) -> Skeleton:
    names: list[str] = []
    parents: list[int] = []
    offsets: list[np.ndarray] = []
    channels: list[tuple[str, ...]] = []
    orders: list[str] = []
    end_sites: list[tuple[int, np.ndarray, str]] = []

    def fix(line: int) -> int:
        return line

    word, line = tok.next("ROOT")
    if word.upper() != "ROOT":
        raise FormatError(path, f"expected ROOT, found {word!r}", fix(line))

    def joint(parent: int) -> None:
        name_tok, line = tok.next("joint name")
        if name_tok == "{":
            raise FormatError(path, "joint without a name", fix(line))
        if name_tok in names:
            raise FormatError(path, f"duplicate joint name {name_tok!r}", fix(line))
        tok.expect("{")
        idx = len(names)
        names.append(name_tok)
        parents.append(parent)
        tok.expect("OFFSET")
        offsets.append(tok.floats(3, f"OFFSET of {name_tok}"))
        word, line = tok.next("CHANNELS")
        chs: tuple[str, ...] = ()
        if word.upper() == "CHANNELS":
            n_tok, line = tok.next("channel count")
            try:
                n = int(n_tok)
            except ValueError:
                raise FormatError(path, f"bad channel count {n_tok!r}", fix(line)) from None
            if not 0 <= n <= 6:
                raise FormatError(path, f"channel count {n} out of range 0-6", fix(line))
            got = []
            for _ in range(n):
                c, cl = tok.next("channel name")
                canon = next((k for k in CHANNEL_NAMES if k.lower() == c.lower()), None)
                if canon is None:
                    raise FormatError(path, f"unknown channel {c!r} on joint {name_tok}", fix(cl))
                if canon in got:
                    raise FormatError(path, f"channel {c!r} repeated on joint {name_tok}", fix(cl))
                got.append(canon)
            chs = tuple(got)
            word, line = tok.next("JOINT, End Site or }")
        channels.append(chs)
        orders.append("".join(c[0] for c in chs if c.endswith("rotation")))
        while True:
            w = word.upper()
            if w == "}":
                return
            if w == "JOINT":
                joint(idx)
            elif w == "END":
                tok.expect("Site")
                tok.expect("{")
                tok.expect("OFFSET")
                off = tok.floats(3, f"End Site OFFSET of {name_tok}")
                tok.expect("}")
                end_sites.append((idx, off, f"{name_tok}_End"))
            else:
                raise FormatError(path, f"unexpected {word!r} in joint {name_tok}", fix(line))
            word, line = tok.next("JOINT, End Site or }")

    joint(-1)
    if tok.pos != len(tok.items):
        extra, line = tok.items[tok.pos]
        raise FormatError(path, f"only one ROOT is supported; found {extra!r} after it", fix(line))
    return Skeleton(
        names=names,
        parents=np.array(parents),
        offsets=np.array(offsets),
        channels=channels,
        rotation_order=orders,
        end_sites=end_sites,
        angle_unit="deg",
    )


def _parse_motion(lines: list[str], motion_line: int, n_channels: int, path: Path,
                  rows: bool = True) -> tuple[np.ndarray, float]:
    """The frame rows (``(frames, channels)``; none with ``rows=False``) and the frame time after MOTION."""
    i = motion_line + 1

    def header(key: str) -> str:
        nonlocal i
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines):
            raise FormatError(path, f"missing '{key}' line after MOTION (truncated file?)", i)
        line = lines[i]
        if not line.strip().lower().startswith(key.lower()):
            raise FormatError(path, f"expected '{key}', found {line.strip()[:40]!r}", i + 1)
        i += 1
        return line.split(":", 1)[1].strip() if ":" in line else ""

    frames_txt = header("Frames:")
    try:
        frames = int(frames_txt)
    except ValueError:
        raise FormatError(path, f"bad frame count {frames_txt!r}", i) from None
    time_txt = header("Frame Time:")
    try:
        frame_time = float(time_txt)
    except ValueError:
        raise FormatError(path, f"bad frame time {time_txt!r}", i) from None
    if frames < 0:
        raise FormatError(path, f"negative frame count {frames}", i)
    if not (frame_time > 0 and np.isfinite(frame_time)):
        raise FormatError(path, f"frame time must be positive, got {frame_time}", i)
    if not rows:
        return np.zeros((0, n_channels)), frame_time
    body = [ln for ln in lines[i:] if ln.strip()]
    first_data_line = i + 1
    if len(body) < frames:
        raise FormatError(
            path, f"truncated: header says {frames} frames, found {len(body)} rows", len(lines)
        )
    if len(body) > frames:
        raise FormatError(path, f"header says {frames} frames but {len(body)} rows follow", first_data_line)
    try:  # numpy's C parser: no Python string per value (a few times less memory at its peak, faster)
        data = np.loadtxt(body, dtype=np.float64, comments=None, ndmin=2) if frames else np.zeros((0, n_channels))
    except ValueError:  # a row of another length, or a number numpy's parser does not read (below)
        data = None
    if data is None or data.shape != (frames, n_channels):  # which row (values counted only here)
        counts = np.fromiter((len(ln.split()) for ln in body), dtype=np.int64, count=len(body))
        bad = np.flatnonzero(counts != n_channels)
        if bad.size:
            row = int(bad[0])
            raise FormatError(
                path,
                f"frame {row + 1} has {counts[row]} values, the hierarchy declares {n_channels} channels",
                _line_of_row(lines, i, row),
            )
        data = None  # every row of the right length: Python's reading below
    if data is None:
        for row, ln in enumerate(body):
            try:
                [float(t) for t in ln.split()]
            except ValueError:
                raise FormatError(path, f"non-numeric value in frame {row + 1}", _line_of_row(lines, i, row)) from None
        # numbers Python reads and numpy's parser does not (e.g. "1_000"): Python's reading
        data = np.array(" ".join(body).split(), dtype=np.float64).reshape(frames, n_channels)
    finite = np.isfinite(data)
    if not finite.all():
        row = int(np.flatnonzero(~finite.all(axis=1))[0])
        raise FormatError(path, f"non-finite value (NaN/inf) in frame {row + 1}", _line_of_row(lines, i, row))
    return data, frame_time


def _line_of_row(lines: list[str], start: int, row: int) -> int:
    seen = -1
    for k in range(start, len(lines)):
        if lines[k].strip():
            seen += 1
            if seen == row:
                return k + 1
    return len(lines)


def _set_units(skeleton: Skeleton) -> None:
    if CMU_JOINTS <= set(skeleton.names):
        skeleton.unit_cm, skeleton.unit_note = CMU_UNIT_CM, "CMU skeleton: 1 unit = 2.54/0.45 cm"
        return
    skeleton.unit_cm, skeleton.unit_note = guess_unit_cm(rest_height(skeleton))


def write_bvh(motion: Motion, path: str | os.PathLike[str], force: bool = False) -> None:
    """Write a :class:`Motion` as BVH, at the source's decimals where known (else 6)."""
    head = bvh_head(motion, motion.n_frames, path)
    if not np.isfinite(motion.channels).all():
        raise FormatError(path, "refusing to write non-finite channel values")
    def write(tmp: Path) -> None:  # the rows a few thousand at a time (a long clip's text is not made whole)
        with open(tmp, "w") as f:
            f.write(head)
            if motion.n_frames:
                f.writelines(row_texts(motion.channels, bvh_decimals(motion)))

    atomic_write(path, write, force=force)


def bvh_decimals(motion: Motion) -> Any:
    """The decimals the rows are written with (the source's, else None: shortest exact)."""
    return motion.decimals if motion.decimals is not None else motion.metadata.get("write_decimals", None)


def bvh_head(motion: Motion, frames: int, path: str | os.PathLike[str] | None = None) -> str:
    """The text of a BVH file up to its first frame row (HIERARCHY, MOTION, ``Frames: frames``, Frame Time)."""
    sk = motion.skeleton
    if sk.angle_unit != "deg":
        raise FormatError(path, "BVH stores degrees; convert the motion first")
    if not sk.has_identity_axes():
        raise FormatError(path, "this skeleton has ASF axis frames; write it as .amc (or convert)")
    out: list[str] = ["HIERARCHY"]
    ends: dict[int, list[np.ndarray]] = {}
    for j, off, _ in sk.end_sites:
        ends.setdefault(j, []).append(off)

    def num(v: float) -> str:
        text = repr(float(v))
        return text[:-2] if text.endswith(".0") else text

    def emit(j: int, depth: int) -> None:
        ind = "\t" * depth
        kind = "ROOT" if sk.parents[j] < 0 else "JOINT"
        out.append(f"{ind}{kind} {sk.names[j]}")
        out.append(f"{ind}{{")
        out.append(f"{ind}\tOFFSET " + " ".join(num(v) for v in sk.offsets[j]))
        if sk.channels[j]:
            out.append(f"{ind}\tCHANNELS {len(sk.channels[j])} " + " ".join(sk.channels[j]))
        for c in sk.children(j):
            emit(c, depth + 1)
        for off in ends.get(j, []):
            out.extend([f"{ind}\tEnd Site", f"{ind}\t{{",
                        f"{ind}\t\tOFFSET " + " ".join(num(v) for v in off), f"{ind}\t}}"])
        out.append(f"{ind}}}")

    for root in np.flatnonzero(sk.parents < 0):
        emit(int(root), 0)
    frame_time = motion.metadata.get("frame_time", 1.0 / motion.frame_rate)
    out += ["MOTION", f"Frames: {frames}", f"Frame Time: {frame_time:.7g}"]
    return "\n".join(out) + "\n"


def parse_bvh_head(lines: list[str], path: Path) -> tuple[Skeleton, float]:
    """Skeleton and frame time of a BVH's text up to and including its ``Frame Time:`` line (the ``Frames:``
    count is not used: a stream does not know it)."""
    if not lines or lines[0].strip().upper() != "HIERARCHY":
        raise FormatError(path, "not a BVH file (first line is not HIERARCHY)", 1)
    motion_line = next((i for i, ln in enumerate(lines) if ln.strip().upper() == "MOTION"), None)
    if motion_line is None:
        raise FormatError(path, "no MOTION section (truncated file?)", len(lines))
    skeleton = _parse_hierarchy(_Tokens(lines[1:motion_line], path, first_line=2), path)
    _, frame_time = _parse_motion(lines, motion_line, skeleton.n_channels, path, rows=False)
    _set_units(skeleton)
    return skeleton, frame_time
