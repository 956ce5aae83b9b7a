"""A checked C3D file split into its marker positions and a :class:`~mocapz.model.c3d_extras.C3DExtras`
holding everything else as stored (see that module), and the reverse: the file's bytes from positions and
extras (:func:`c3d_bytes`).

Points named in the POINT group's ANGLES, FORCES, MOMENTS, POWERS, REACTIONS or SCALARS lists, or in a
list POINT:TYPE_GROUPS declares (Plug-in-Gait model outputs), are not marker positions: they become the
extras' tracks, with the unit of their list (``POINT:ANGLE_UNITS``...). Positions are the stored values:
float32 values for float storage, and ``float64(int16) * float64(|scale|)`` for integer storage, which
:meth:`C3DExtras.words` turns back into the same integers.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from mocapz.errors import FormatError
from mocapz.io.c3d_checks import BLOCK, PROCESSORS, C3DLayout
from mocapz.model.c3d_extras import TRACK_UNIT_PARAMS, C3DExtras, float_words, word_dtype


def split_c3d(path: Path, layout: C3DLayout) -> tuple[list[str], np.ndarray, C3DExtras]:
    """Read the file's words: marker labels, positions ``(frames, markers, 3)`` float64 in POINT:UNITS
    with NaN where missing (a negative residual word or a non-finite value), and the extras."""
    raw = _file_bytes(path)
    h = layout.header
    start = layout.data_offset
    end = start + layout.frames * layout.frame_values * layout.value_bytes
    dtype = word_dtype(h.processor, h.is_float)
    words = np.frombuffer(raw[start:end], dtype=dtype).astype(np.int64).reshape(layout.frames, layout.frame_values)
    n = layout.points
    point_words = words[:, :4 * n].reshape(layout.frames, n, 4)
    labels = _labels(layout, n)
    kinds = _track_kinds(layout, labels)
    tracks = np.array([i for i in range(n) if kinds[i]], dtype=np.int64)
    markers = np.array([i for i in range(n) if not kinds[i]], dtype=np.int64)
    extras = C3DExtras(
        header=raw[:BLOCK], gap=raw[BLOCK:(h.param_block - 1) * BLOCK], params=raw[(h.param_block - 1) * BLOCK:start],
        tail=raw[end:], processor=h.processor, is_float=h.is_float, scales=point_scales(layout),
        marker_index=markers, track_index=tracks, track_labels=[labels[i] for i in tracks],
        track_kinds=[kinds[i] for i in tracks], track_units=[_unit(layout, kinds[i]) for i in tracks],
        residual_words=point_words[:, :, 3].copy(), track_words=point_words[:, tracks, :3].copy(),
        fix_mask=np.zeros((layout.frames, markers.size), dtype=bool),
        fix_words=np.zeros((layout.frames, markers.size, 3), dtype=np.int64),
        analog_words=words[:, 4 * n:].reshape(layout.frames * layout.samples, layout.channels).copy(),
        samples=layout.samples, frame_params=_frame_params(raw, layout), analog_scales=_analog_scales(layout),
        analog_labels=_analog_labels(layout))
    stored = point_words[:, markers, :3]
    positions = extras.values(stored, markers)
    missing = (extras.residual_values()[:, markers] < 0) | ~np.isfinite(positions).all(axis=2)
    positions[missing] = np.nan
    fix = missing | (extras.words(positions, markers) != stored).any(axis=2)
    extras.fix_mask = fix
    extras.fix_words = np.where(fix[:, :, None], stored, 0)
    return [labels[i] for i in markers], positions, extras


def c3d_bytes(positions: np.ndarray, extras: C3DExtras) -> bytes:
    """The C3D file of marker ``positions`` ``(frames, markers, 3)`` and ``extras`` (same frames and
    markers): a marker sample that is NaN and has no stored words is written missing (0, 0, 0, -1)."""
    f, n = extras.frames, extras.points
    words = np.zeros((f, 4 * n + extras.samples * extras.channels), dtype=np.int64)
    point = words[:, :4 * n].reshape(f, n, 4)
    point[:, :, 3] = extras.residual_words
    point[:, extras.track_index, :3] = extras.track_words
    m = extras.marker_index
    xyz = extras.words(positions, m)
    xyz = np.where(extras.fix_mask[:, :, None], extras.fix_words, xyz)
    point[:, m, :3] = xyz
    lost = ~np.isfinite(positions).all(axis=2) & ~extras.fix_mask
    if lost.any():
        res = point[:, m, 3]
        res[lost] = float_words(np.array([-1.0]), extras.processor)[0] if extras.is_float else -1
        point[:, m, 3] = res
    words[:, 4 * n:] = extras.analog_words.reshape(f, extras.samples * extras.channels)
    data = words.astype(extras.dtype).tobytes()
    body = extras.header + extras.gap + extras.params + data
    if extras.tail is not None:
        return body + extras.tail
    return body + bytes(-len(body) % BLOCK)


def _file_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise FormatError(path, f"could not read the file ({exc.strerror or exc})") from None


def _numbers(layout: C3DLayout, group: str, name: str) -> np.ndarray:
    """A numeric parameter with its ``NAME2``, ``NAME3``... continuations, float64."""
    out = []
    for key in [name] + [f"{name}{i}" for i in range(2, 100)]:
        param = layout.params.get((group, key))
        if param is None:
            break
        out.append(param.numbers(layout.header.processor))
    return np.concatenate(out) if out else np.empty(0)


def point_scales(layout: C3DLayout) -> np.ndarray:
    """``|scale|`` of every point, ``(points,)``: POINT:SCALE's value for the point if it has one for
    each, else its first value, else the header's scale (as ezc3d); float64 of the stored float32."""
    values = np.abs(_numbers(layout, "POINT", "SCALE"))
    if values.size == 0:
        values = np.array([abs(layout.header.scale)])
    scales = np.full(layout.points, values[0])
    n = min(values.size, layout.points)
    scales[:n] = values[:n]
    return scales


def _strings(layout: C3DLayout, group: str, name: str) -> list[str]:
    """A char parameter with its ``NAME2``, ``NAME3``... continuations, blanks stripped."""
    out: list[str] = []
    for key in [name] + [f"{name}{i}" for i in range(2, 100)]:
        param = layout.params.get((group, key))
        if param is None:
            break
        out.extend(s.strip() for s in param.strings())
    return out


def _analog_scales(layout: C3DLayout) -> np.ndarray:
    """``(channels,)`` ``|ANALOG:SCALE * ANALOG:GEN_SCALE|`` (a channel without a SCALE value: 1, as ezc3d)."""
    scales = np.ones(layout.channels)
    values = _numbers(layout, "ANALOG", "SCALE")[:layout.channels]
    scales[:values.size] = values
    gen = _numbers(layout, "ANALOG", "GEN_SCALE")
    return np.abs(scales * (gen[0] if gen.size else 1.0))


def _analog_labels(layout: C3DLayout) -> list[str]:
    """ANALOG:LABELS for every channel (an empty or absent label: ``""``)."""
    labels = _strings(layout, "ANALOG", "LABELS")[:layout.channels]
    return labels + [""] * (layout.channels - len(labels))


def _labels(layout: C3DLayout, n: int) -> list[str]:
    """POINT:LABELS for ``n`` points; an empty or absent label is ``*<number>`` (as the ezc3d path)."""
    labels = _strings(layout, "POINT", "LABELS")[:n]
    labels += [""] * (n - len(labels))
    return [s or f"*{i + 1}" for i, s in enumerate(labels)]


def _unit_params(layout: C3DLayout) -> dict[str, str]:
    """The lists of non-marker points and their unit parameters: the usual ones (ANGLES: ANGLE_UNITS...)
    and those POINT:TYPE_GROUPS declares (pairs of a list name and its unit prefix, as Vicon writes)."""
    out = dict(TRACK_UNIT_PARAMS)
    pairs = [s.upper() for s in _strings(layout, "POINT", "TYPE_GROUPS")]
    for kind, prefix in zip(pairs[0::2], pairs[1::2], strict=False):
        if kind and prefix and kind not in ("LABELS", "DESCRIPTIONS", "UNITS"):
            out.setdefault(kind, f"{prefix}_UNITS")
    return out


def _track_kinds(layout: C3DLayout, labels: list[str]) -> list[str]:
    """Per point, the model-output list naming it (``"ANGLES"``...), ``""`` for a marker."""
    named: dict[str, str] = {}
    for kind in _unit_params(layout):
        for label in _strings(layout, "POINT", kind):
            if label:
                named.setdefault(label, kind)
    return [named.get(s, "") for s in labels]


def _unit(layout: C3DLayout, kind: str) -> str:
    units = _strings(layout, "POINT", _unit_params(layout)[kind])
    return units[0] if units else ""


FRAME_PARAMS = (("POINT", "FRAMES"), ("TRIAL", "ACTUAL_START_FIELD"), ("TRIAL", "ACTUAL_END_FIELD"))


def _frame_params(raw: bytes, layout: C3DLayout) -> dict[str, tuple[int, int, int]]:
    """Where the frame-count-dependent parameters (:data:`FRAME_PARAMS`) hold their values in the parameter
    section: ``{"GROUP:NAME": (byte offset, kind, number of values)}``, for the numeric ones present."""
    start = (layout.header.param_block - 1) * BLOCK
    section = raw[start:layout.data_offset]
    order = PROCESSORS[layout.header.processor]
    out: dict[str, tuple[int, int, int]] = {}
    pos = 4
    while pos + 2 <= len(section):  # the records were checked by c3d_checks
        n_chars, gid = struct.unpack("bb", section[pos:pos + 2])
        if n_chars == 0 or gid == 0:
            break
        name_end = pos + 2 + abs(n_chars)
        (offset,) = struct.unpack(f"{order}H", section[name_end:name_end + 2])
        if gid > 0:
            key = (_group_name(layout, gid, section), section[pos + 2:name_end].decode("latin-1").strip().upper())
            param = layout.params.get(key)
            if key in FRAME_PARAMS and param is not None and param.kind in (2, 4) and param.count >= 1:
                out[":".join(key)] = (name_end + 4 + section[name_end + 3], param.kind, param.count)
        if not offset:
            break
        pos = name_end + offset
    return out


def _group_name(layout: C3DLayout, gid: int, section: bytes) -> str:
    """The name of group ``gid`` (groups are the records with a negative id)."""
    pos = 4
    order = PROCESSORS[layout.header.processor]
    while pos + 2 <= len(section):
        n_chars, g = struct.unpack("bb", section[pos:pos + 2])
        if n_chars == 0 or g == 0:
            break
        name_end = pos + 2 + abs(n_chars)
        if g == -gid:
            return section[pos + 2:name_end].decode("latin-1").strip().upper()
        (offset,) = struct.unpack(f"{order}H", section[name_end:name_end + 2])
        if not offset:
            break
        pos = name_end + offset
    return ""
