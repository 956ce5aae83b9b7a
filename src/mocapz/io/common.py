"""Helpers shared by the format readers and writers: decimal detection, text in and out, safe output, unit guesses."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from mocapz.errors import FormatError, MocapzError
from mocapz.model.skeleton import Skeleton

CMU_UNIT_CM = 2.54 / 0.45  # CMU ASF "length 0.45": 1 unit = 1/0.45 inch = 5.644 cm


DECIMAL_ROWS = 4096  # rows per step of :func:`common_decimals` (its work arrays: 10 bools and a few floats a value)


def exception_budget(rows: int) -> int:
    """How many values of a column of ``rows`` values may miss its common decimals (1 %, at least 1): those
    are kept exactly as per-value exceptions."""
    return rows // 100 + 1


def fits_decimals(values: np.ndarray, decimals: np.ndarray) -> np.ndarray:
    """True where a value is the float64 of a number with ``decimals`` decimals (per column; NaN: False), so
    that ``%.{d}f`` text reads back to the same value (``-0`` included: it prints as ``-0.000``)."""
    scale = 10.0 ** np.asarray(decimals, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        scaled = values * scale
        return (np.abs(scaled) < 2.0**52) & (np.round(scaled) / scale == values)


def detect_decimals(values: np.ndarray, max_decimals: int = 9) -> np.ndarray | None:
    """Smallest decimal count per column that represents every value exactly (``None`` if some column needs
    more than ``max_decimals``); :func:`common_decimals` allows a few exceptions."""
    return common_decimals(values, max_decimals, exceptions=False)


def common_decimals(values: np.ndarray, max_decimals: int = 9, exceptions: bool = True) -> np.ndarray | None:
    """The common decimal count of each column: the smallest that represents every value that has at most
    ``max_decimals`` decimals. The few others (at most :func:`exception_budget`: float artefacts such as
    ``-0.00709999999999``) are exceptions, kept exactly by the lossless codec and written back with ``repr``;
    none are allowed with ``exceptions=False``.

    Args:
        values: ``(rows, columns)`` float64 parsed from decimal text.

    Returns:
        ``(columns,)`` int64, or ``None`` if some column has more values than that off every decimal count
        up to ``max_decimals`` (then the values are kept as float64).
    """
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
    rows, cols = values.shape
    budget = exception_budget(rows) if exceptions else 0
    slack = rows // 100 if exceptions else 0  # values with a few more decimals than the rest: exceptions too
    never = np.zeros(cols, dtype=np.int64)  # per column: finite values off every count
    misses = np.zeros((max_decimals + 1, cols), dtype=np.int64)  # per count and column: fittable values off it
    for a in range(0, rows, DECIMAL_ROWS):  # a few thousand rows at a time: counts add up, the arrays stay small
        part = values[a:a + DECIMAL_ROWS]
        finite = np.isfinite(part)
        fit = np.stack([fits_decimals(part, np.full(cols, d)) for d in range(max_decimals + 1)])
        off = finite & ~fit.any(axis=0)
        never += off.sum(axis=0)
        misses += ((finite & ~off)[None] & ~fit).sum(axis=1)
    if (never > budget).any():
        return None
    ok = misses <= slack  # (decimals, cols)
    if not ok.any(axis=0).all():
        return None
    return np.argmax(ok, axis=0).astype(np.int64)


def exact_text_mask(values: np.ndarray, decimals: np.ndarray) -> np.ndarray:
    """``(rows, columns)`` True for the finite values a writer must write with ``repr`` to read back exactly:
    those off their column's decimals, in columns where they are few (:func:`exception_budget`). Columns
    where most values are off (decoded by a lossy codec) are rounded to the decimals instead."""
    off = np.empty(values.shape, dtype=bool)
    for a in range(0, values.shape[0], DECIMAL_ROWS):  # a few thousand rows at a time (the same values)
        part = values[a:a + DECIMAL_ROWS]
        off[a:a + DECIMAL_ROWS] = ~fits_decimals(part, decimals) & np.isfinite(part)
    few = off.sum(axis=0) <= exception_budget(values.shape[0])
    return off & few[None, :]


#: Heights of a standing adult body, centimetres: a skeleton's unit is guessed as the candidate unit that
#: puts its rest height in this range.
HUMAN_HEIGHT_CM = (120.0, 220.0)

#: Candidate length units of skeletal files: (centimetres per unit, name). The ranges of rest heights they
#: accept do not overlap (CMU 21-39 units, inches 47-87, cm 120-220, m 1.2-2.2, mm 1200-2200).
UNIT_CANDIDATES: tuple[tuple[float, str], ...] = (
    (100.0, "metres"),
    (1.0, "centimetres"),
    (0.1, "millimetres"),
    (2.54, "inches"),
    (CMU_UNIT_CM, "CMU units (inch/0.45)"),
)


def guess_unit_cm(height: float) -> tuple[float | None, str]:
    """Guess centimetres per unit from a standing skeleton's height in file units.

    Args:
        height: height of the body in file units (:func:`rest_height`; NaN: its measures disagree).

    Returns:
        ``(cm_per_unit, note)``: the candidate unit of :data:`UNIT_CANDIDATES` making the body 1.2-2.2 m
        tall, or ``None`` (unknown) when none does; the note says how it was decided.
    """
    lo, hi = HUMAN_HEIGHT_CM
    if np.isnan(height):
        return None, ("unknown (the skeleton's rest pose and its bone chains give human heights in different "
                      "units; say it with --unit)")
    fits = [(cm, name) for cm, name in UNIT_CANDIDATES if lo <= height * cm <= hi]
    if len(fits) == 1:
        cm, name = fits[0]
        return cm, f"guessed from skeleton height {height:.3g}: {name} ({height * cm:.0f} cm tall)"
    return None, (f"unknown (skeleton height {height:.3g} in file units is no human height of "
                  f"{lo / 100:g}-{hi / 100:g} m in cm, m, mm, in or CMU units; say it with --unit)")


#: Longest bone path between two points of a human skeleton (toe to fingertip: leg + spine + arm) over the
#: standing height: 1.41-1.67 on every shared BVH and ASF skeleton (measured against their clips' heights).
SPAN_PER_HEIGHT = 1.5


def rest_height(skeleton: Skeleton) -> float:
    """Height of the body in file units, for the unit guess (:func:`guess_unit_cm`).

    The body is the subtree of the first joint that branches (:meth:`Skeleton.body_points`): a chain of
    helper joints above it (a locomotion root on the floor, far from the hips, as in the Bandai-Namco rigs)
    does not count. Two measures of its proportions are taken: the largest extent of the body in the rest
    pose (all channels zero, offsets only) along any axis, and the pose-free :func:`chain_span` divided by
    :data:`SPAN_PER_HEIGHT`. The rest extent is returned when it is a human height in some candidate unit
    that the chains do not contradict; the chain height when only it is a human height (a rest pose that is
    not a standing one); NaN (unit unknown) when the two are human heights in different units.
    """
    from mocapz.model.kinematics import chain

    rot = np.broadcast_to(np.eye(3), (1, skeleton.n_joints, 3, 3)).copy()
    pos, _ = chain(skeleton, rot, skeleton.offsets[None].copy())
    box = float(np.ptp(pos[0][skeleton.body_points()], axis=0).max())
    span = chain_span(skeleton) / SPAN_PER_HEIGHT
    by_box, by_span = guess_unit_cm(box)[0], guess_unit_cm(span)[0]
    if by_box is not None and by_span is not None and by_box != by_span:
        return float("nan")
    return span if by_box is None and by_span is not None else box


def chain_span(skeleton: Skeleton) -> float:
    """Longest path along the bones between two points of the body (sum of bone lengths, file units): for a
    human, toe to fingertip. It does not depend on the rest pose."""
    body = skeleton.body_points()
    ends = np.array([o for _, o, _ in skeleton.end_sites], dtype=np.float64).reshape(-1, 3)
    length = np.linalg.norm(np.concatenate([skeleton.offsets, ends]), axis=1)
    parents = skeleton.point_parents
    inside = np.zeros(skeleton.n_points, dtype=bool)
    inside[body] = True
    first = np.zeros(skeleton.n_points)  # longest path down from each point, and the second longest
    second = np.zeros(skeleton.n_points)
    for p in body[::-1]:  # children after parents: every point's paths are known before its parent's
        q = parents[p]
        if q >= 0 and inside[q]:
            d = first[p] + length[p]
            if d > first[q]:
                first[q], second[q] = d, first[q]
            elif d > second[q]:
                second[q] = d
    return float((first + second)[body].max())


def atomic_write(path: str | os.PathLike[str], write: Callable[[Path], None], force: bool = False) -> None:
    """Write a file through a temporary file in the same folder, then rename it into place.

    ``write`` receives the temporary path. An existing ``path`` is kept unless ``force``; on any error
    the temporary file is removed, so no partial output is ever left behind.
    """
    path = Path(path)
    if path.exists() and not force:
        raise MocapzError(f"{path}: output exists (use -f / force=True to overwrite)")
    if not path.parent.exists():
        raise MocapzError(f"{path}: output folder {path.parent} does not exist")
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix + ".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        write(tmp)
        os.chmod(tmp, 0o644 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def read_bytes(path: str | os.PathLike[str]) -> bytes:
    """The bytes of a file, raising :class:`FormatError` naming it when it is missing or a folder."""
    p = Path(path)
    if not p.exists():
        raise FormatError(p, "no such file")
    if p.is_dir():
        raise FormatError(p, "is a folder, not a file")
    return p.read_bytes()


def read_text(path: str | os.PathLike[str]) -> str:
    """Read a text file, raising :class:`FormatError` for missing, empty or non-text files."""
    p = Path(path)
    data = read_bytes(p)
    if not data.strip():
        raise FormatError(p, "file is empty")
    if b"\x00" in data[:4096]:
        raise FormatError(p, "binary data where a text file was expected")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def format_rows(values: np.ndarray, decimals: np.ndarray | int | None, sep: str = " ") -> str:
    """Format a ``(rows, columns)`` array as text lines with fixed decimals per column (:func:`row_texts`
    joined)."""
    return "".join(row_texts(values, decimals, sep))


def row_texts(values: np.ndarray, decimals: np.ndarray | int | None, sep: str = " ") -> Iterator[str]:
    """The text lines of a ``(rows, columns)`` array, :data:`DECIMAL_ROWS` rows a piece (each ending in a newline;
    no rows: one newline), so that a long clip's text is written without all of it in memory at once.

    ``decimals=None`` writes the shortest text that reads back to the same float64 (``repr``). With decimals,
    the few values off their column's decimals (:func:`exact_text_mask`) are written with ``repr`` too, and
    ``-0`` as ``-0.000``, so values read from a file are written back exactly; values of lossy columns
    are rounded (those that round to zero without being zero are written ``0.000``, not ``-0.000``).
    """
    values = np.asarray(values, dtype=np.float64)
    if not values.shape[0]:
        yield "\n"
        return
    if decimals is None:
        for a in range(0, values.shape[0], DECIMAL_ROWS):
            yield "\n".join(sep.join(map(repr, row)) for row in values[a:a + DECIMAL_ROWS].tolist()) + "\n"
        return
    cols = values.shape[1]
    dec = np.broadcast_to(np.asarray(decimals, dtype=np.int64), (cols,))
    fmts = [f"%.{int(d)}f" for d in dec]
    fmt = sep.join(fmts)
    exact = exact_text_mask(values, dec)
    half = 0.5 * 10.0 ** (-dec.astype(float))
    for a in range(0, values.shape[0], DECIMAL_ROWS):
        part, ex = values[a:a + DECIMAL_ROWS], exact[a:a + DECIMAL_ROWS]
        noise = (np.abs(part) < half) & ~fits_decimals(part, dec) & ~ex
        lines = [fmt % tuple(row) for row in np.where(noise, 0.0, part).tolist()]
        for r in np.flatnonzero(ex.any(axis=1)).tolist():
            lines[r] = sep.join(repr(v) if e else f % v
                                for f, v, e in zip(fmts, part[r].tolist(), ex[r].tolist(), strict=True))
        yield "\n".join(lines) + "\n"


def snap_rate(rate: float) -> float:
    """Round a frame rate computed from a rounded frame time (1/0.0083333) to the nearest integer."""
    r = round(rate)
    return float(r) if r > 0 and abs(rate - r) < 1e-3 * r else float(rate)
