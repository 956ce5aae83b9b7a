"""Acclaim AMC motion files: read an AMC and its ASF skeleton into a Motion, write a Motion back as both.

An AMC file is a header (comments, ``:FULLY-SPECIFIED``, ``:DEGREES`` / ``:RADIANS``) followed by one
record per frame: the frame number on its own line, then one line per bone with that bone's dof values
in ASF ``dof`` order. The skeleton is the ASF file (:mod:`mocapz.io.asf` reads it,
:mod:`mocapz.io.asf_write` produces the one written beside the AMC).

Channel values stay as in the file (degrees for ``:DEGREES``), ``(frames, DOFs)`` with the columns
grouped per joint in skeleton (depth-first) order. Translation dofs of non-root bones replace the
joint's offset (the project's BVH convention); root translations are absolute.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from mocapz.errors import FormatError, MocapzError
from mocapz.io.asf import Asf, build_skeleton, find_asf, parse_asf
from mocapz.io.asf_write import asf_for
from mocapz.io.common import atomic_write, common_decimals, exact_text_mask, read_text
from mocapz.model.motion import Motion
from mocapz.model.skeleton import Skeleton

DEFAULT_FRAME_RATE = 120.0  # CMU capture rate; the AMC format has no rate field


# ============================================================================ reading
def read_asfamc(
    amc: str | os.PathLike[str],
    asf: str | os.PathLike[str] | None = None,
    *,
    frame_rate: float = DEFAULT_FRAME_RATE,
) -> Motion:
    """Read an AMC motion and its ASF skeleton into a :class:`Motion`.

    Args:
        amc: the ``.amc`` file.
        asf: the ``.asf`` skeleton; by default found by :func:`find_asf` (``<stem>.asf`` beside the AMC,
            else the ``.asf`` whose stem starts the AMC's stem, else the folder's only ``.asf``).
        frame_rate: frames per second (AMC files do not store it; CMU captures at 120).

    Returns:
        A motion whose channels ``(frames, DOFs)`` hold the AMC values in file units and the AMC's
        angle unit, columns grouped per joint in skeleton (depth-first) order.
    """
    amc = Path(amc)
    amc_text = read_text(amc)
    asf_path = find_asf(amc) if asf is None else Path(asf)
    skel = parse_asf(asf_path)
    lines = amc_text.splitlines()
    header, start, angle = _amc_header(lines, amc, skel.angle_unit)
    dofs = {name: len(skel.bone(name).dofs) for name in skel.order()}
    bones, data, first = _parse_amc_frames(lines, start, amc, dofs)
    sk = build_skeleton(skel, bones)
    sk.angle_unit = angle
    channels = data[:, _amc_to_skeleton_columns(sk, bones, skel)]
    return Motion(
        skeleton=sk,
        channels=channels,
        frame_rate=float(frame_rate),
        name=amc.stem,
        source_format="asfamc",
        decimals=exact_decimals(channels),
        metadata={
            "path": str(amc),
            "asf_path": str(asf_path),
            "file_bytes": amc.stat().st_size + asf_path.stat().st_size,
            "amc_header": header,
            "amc_first_frame": first,
        },
    )


def exact_decimals(channels: np.ndarray) -> np.ndarray | None:
    """The common decimals per column ``(channels,)`` (:func:`~mocapz.io.common.common_decimals`), or ``None``.

    AMC files write 6 significant digits (``%g``), so a column may hold a few tiny values such as
    ``3.64024e-015`` beside its ordinary ones: those are per-value exceptions (kept exactly by the lossless
    codec, written back with ``repr``), not a reason to give the whole clip up.
    """
    return common_decimals(channels) if channels.size else None


# ---------------------------------------------------------------------------- frame records
def _amc_header(lines: list[str], path: Path, default_angle: str) -> tuple[list[str], int, str]:
    """Header comment lines, index of the first frame-number line, and the angle unit of the values."""
    angle, header = default_angle, []
    for i, raw in enumerate(lines):
        s = raw.strip()
        if not s:
            continue
        if s.startswith("#"):
            header.append(s)
        elif s.startswith(":"):
            key = s.split()[0].upper()
            if key in (":DEGREES", ":RADIANS"):
                angle = "deg" if key == ":DEGREES" else "rad"
            elif key != ":FULLY-SPECIFIED":
                header.append(s)
        elif s.isdigit():
            return header, i, angle
        else:
            raise FormatError(path, f"expected a frame number, found {s[:40]!r}", i + 1)
    raise FormatError(path, "no frames (no frame-number line after the header)", len(lines))


def _parse_amc_frames(
    lines: list[str], start: int, path: Path, dofs: dict[str, int]
) -> tuple[list[str], np.ndarray, int]:
    """Parse the frame records.

    Returns:
        the bones of a frame in the first frame's line order, the values ``(frames, DOFs)`` in that
        column order, and the first frame number.
    """
    tokens: list[str] = []
    frame_lines: list[int] = []
    frame_nos: list[int] = []
    permuted: dict[int, tuple[str, ...]] = {}
    first: list[str] | None = None
    cur: list[str] = []
    cur_lines: list[int] = []

    def close() -> None:
        nonlocal first
        if first is None:
            _check_unique(cur, cur_lines, frame_lines[-1], path)
            first = list(cur)
        elif cur != first:
            _check_same_bones(first, cur, cur_lines, frame_lines[-1], frame_nos[-1], path)
            permuted[len(frame_nos) - 1] = tuple(cur)

    for i in range(start, len(lines)):
        parts = lines[i].split()
        if not parts or parts[0][0] == "#":
            continue
        head = parts[0]
        if len(parts) == 1 and head.isdigit():
            if frame_nos:
                close()
            frame_nos.append(int(head))
            frame_lines.append(i + 1)
            cur, cur_lines = [], []
            continue
        n = dofs.get(head)
        if n is None:
            raise FormatError(path, f"bone {head!r} is not in the ASF skeleton", i + 1)
        if len(parts) - 1 != n:
            raise FormatError(path, f"bone {head!r} has {len(parts) - 1} values, its ASF dofs are {n}", i + 1)
        cur.append(head)
        cur_lines.append(i + 1)
        tokens.extend(parts[1:])
    close()
    assert first is not None
    _check_frame_numbers(frame_nos, frame_lines, path)
    data = _to_floats(tokens, lines, start, path).reshape(len(frame_nos), -1)
    _check_finite(data, frame_lines, path)
    _unpermute(data, first, permuted, dofs)
    return first, data, frame_nos[0]


def _check_unique(bones: list[str], lines: list[int], frame_line: int, path: Path) -> None:
    seen: set[str] = set()
    for b, ln in zip(bones, lines, strict=True):
        if b in seen:
            raise FormatError(path, f"bone {b!r} appears twice in one frame", ln)
        seen.add(b)
    if not bones:
        raise FormatError(path, "first frame has no bone lines", frame_line)


def _check_same_bones(
    first: list[str], cur: list[str], cur_lines: list[int], frame_line: int, frame_no: int, path: Path
) -> None:
    ref = set(first)
    seen: set[str] = set()
    for b, ln in zip(cur, cur_lines, strict=True):
        if b not in ref:
            raise FormatError(path, f"frame {frame_no}: bone {b!r} is not in the first frame", ln)
        if b in seen:
            raise FormatError(path, f"frame {frame_no}: bone {b!r} appears twice", ln)
        seen.add(b)
    missing = [b for b in first if b not in seen]
    if missing:
        last = cur_lines[-1] if cur_lines else frame_line
        raise FormatError(
            path, f"frame {frame_no} is incomplete (truncated?): no line for {', '.join(missing[:5])}", last
        )


def _check_frame_numbers(frame_nos: list[int], frame_lines: list[int], path: Path) -> None:
    nos = np.asarray(frame_nos, dtype=np.int64)
    bad = np.flatnonzero(np.diff(nos) != 1)
    if bad.size:
        k = int(bad[0]) + 1
        raise FormatError(path, f"frame number {nos[k]} follows {nos[k - 1]} (frames must be consecutive)",
                          frame_lines[k])


def _to_floats(tokens: list[str], lines: list[str], start: int, path: Path) -> np.ndarray:
    try:
        return np.array(tokens, dtype=np.float64)
    except ValueError:
        for i in range(start, len(lines)):
            parts = lines[i].split()
            for t in parts[1:]:
                try:
                    float(t)
                except ValueError:
                    raise FormatError(path, f"non-numeric value {t!r} for bone {parts[0]!r}", i + 1) from None
        raise


def _check_finite(data: np.ndarray, frame_lines: list[int], path: Path) -> None:
    finite = np.isfinite(data)
    if finite.all():
        return
    f = int(np.flatnonzero(~finite.all(axis=1))[0])
    raise FormatError(path, "non-finite value (NaN/inf) in the frame record starting here", frame_lines[f])


def _unpermute(data: np.ndarray, first: list[str], permuted: dict[int, tuple[str, ...]],
               dofs: dict[str, int]) -> None:
    """Reorder the columns of frames whose bone lines came in another order than the first frame's."""
    if not permuted:
        return
    cache: dict[tuple[str, ...], np.ndarray] = {}
    for f, order in permuted.items():
        if order not in cache:
            cols = _bone_columns(list(order), dofs)
            cache[order] = np.concatenate([cols[b] for b in first])
        data[f] = data[f][cache[order]]


def _bone_columns(bones: list[str], dofs: dict[str, int]) -> dict[str, np.ndarray]:
    out, start = {}, 0
    for b in bones:
        out[b] = np.arange(start, start + dofs[b])
        start += dofs[b]
    return out


def _amc_to_skeleton_columns(sk: Skeleton, bones: list[str], asf: Asf) -> np.ndarray:
    """For each skeleton column, its column in the AMC frame (bones in ``bones`` order)."""
    cols = _bone_columns(bones, {b: len(asf.bone(b).dofs) for b in bones})
    parts = [cols[name] for name, chs in zip(sk.names, sk.channels, strict=True) if chs]
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)


# ============================================================================ writing
def write_asfamc(motion: Motion, amc_path: str | os.PathLike[str], force: bool = False) -> list[Path]:
    """Write ``motion`` as an AMC file and its skeleton as ``<stem>.asf`` beside it.

    A skeleton read from ASF is written back verbatim (its ASF text is kept in ``skeleton.extra``);
    any other skeleton (e.g. from BVH) gets a generated ASF whose FK reproduces the motion's joint and
    end-site positions (see :func:`~mocapz.io.asf_write.generate_asf`). Values are written at
    ``motion.decimals`` where known, else as the shortest text that reads back to the same float64.
    Both files are written atomically; existing files are kept unless ``force`` (an existing identical
    ASF is fine), and nothing is left behind on failure.

    Returns:
        ``[amc_path, asf_path]``.
    """
    amc_path = Path(amc_path)
    asf_path = amc_path.with_suffix(".asf")
    if amc_path.suffix.lower() != ".amc":
        raise MocapzError(f"{amc_path}: an AMC output needs the .amc extension")
    if not np.isfinite(motion.channels).all():
        raise FormatError(amc_path, "refusing to write non-finite channel values")
    asf_text, layout = asf_for(motion.skeleton, asf_path)
    amc_text = _amc_text(motion, asf_path, layout)
    asf_is_same = asf_path.exists() and asf_path.read_bytes() == asf_text.encode("utf-8")
    if amc_path.exists() and not force:
        raise MocapzError(f"{amc_path}: output exists (use -f / force=True to overwrite)")
    if asf_path.exists() and not force and not asf_is_same:
        raise MocapzError(f"{asf_path}: a different skeleton file exists (use -f / force=True to overwrite)")
    old_asf = asf_path.read_bytes() if asf_path.exists() else None
    if not asf_is_same:
        _write_bytes(asf_path, asf_text.encode("utf-8"))
    try:
        atomic_write(amc_path, lambda tmp: tmp.write_bytes(amc_text.encode("utf-8")), force=force)
    except BaseException:
        if not asf_is_same:  # put the skeleton file back as it was
            if old_asf is None:
                asf_path.unlink(missing_ok=True)
            else:
                _write_bytes(asf_path, old_asf)
        raise
    return [amc_path, asf_path]


def _write_bytes(path: Path, data: bytes) -> None:
    atomic_write(path, lambda tmp: tmp.write_bytes(data), force=True)


def _amc_text(motion: Motion, asf_path: Path, layout: dict[str, tuple[int, tuple[str, ...]]]) -> str:
    """The whole AMC file: header, then one record per frame, bones and columns as ``layout`` says."""
    sk = motion.skeleton
    slices = sk.channel_slices()
    cols: list[int] = []
    template = ["%d\n"]
    plain_template = ["%d\n"]
    for j, chs in layout.values():
        cols.extend(slices[j].start + sk.channels[j].index(c) for c in chs)
    if sorted(cols) != list(range(sk.n_channels)):
        raise MocapzError("internal error: AMC columns do not cover the motion's channels")
    values = motion.channels[:, cols]
    dec = None if motion.decimals is None else np.asarray(motion.decimals, dtype=np.int64)[cols]
    fmts = iter(["%r"] * len(cols) if dec is None else [f"%.{int(d)}f" for d in dec])
    for bone, (_, chs) in layout.items():
        template.append(bone.replace("%", "%%") + "".join(" " + next(fmts) for _ in chs) + "\n")
        plain_template.append(bone.replace("%", "%%") + " %s" * len(chs) + "\n")
    fmt = "".join(template)
    exact = np.zeros(values.shape, dtype=bool)
    if dec is not None:  # the few values off the decimals are written with repr; no "-0.000" rounding noise
        exact = exact_text_mask(values, dec)
        noise = np.abs(values) < 0.5 * 10.0 ** (-dec.astype(float))
        values = np.where(noise & ~exact & (values != 0), 0.0, values)
    first = int(motion.metadata.get("amc_first_frame", 1))
    header = _amc_header_lines(motion, sk.angle_unit, asf_path)
    frames = [fmt % (first + f, *row) for f, row in enumerate(values.tolist())]
    if exact.any():
        plain = "".join(plain_template)
        for f in np.flatnonzero(exact.any(axis=1)).tolist():
            assert dec is not None
            texts = [repr(v) if e else f"%.{int(d)}f" % v
                     for v, e, d in zip(values[f].tolist(), exact[f].tolist(), dec.tolist(), strict=True)]
            frames[f] = plain % (first + f, *texts)
    return header + "".join(frames)

def _amc_header_lines(motion: Motion, angle_unit: str, asf_path: Path) -> str:
    kept = [h for h in motion.metadata.get("amc_header", []) if not h.upper().startswith("#!OML:ASF")]
    lines = [f"#!OML:ASF {asf_path.name}", *kept, ":FULLY-SPECIFIED",
             ":DEGREES" if angle_unit == "deg" else ":RADIANS"]
    return "\n".join(lines) + "\n"
