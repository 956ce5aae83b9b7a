"""PGA decoder: rebuild trajectories, express end effectors in the root frame, solve the IK, write channels."""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Hashable
from dataclasses import dataclass, replace
from itertools import pairwise
from typing import Any

import numpy as np

from mocapz.codecs.correction.window import seekable
from mocapz.codecs.pga import ikjit, lifting, turns
from mocapz.codecs.pga.channels import Unwrapper, channels_from_rotations, euler_tables, finish_channels
from mocapz.codecs.pga.clip import targets_in_root_frame
from mocapz.codecs.pga.effectors import effector_points
from mocapz.codecs.pga.ik import IKProblem, make_problem
from mocapz.codecs.pga.iksolve import pose, solve_fast
from mocapz.codecs.pga.joints import check_skeleton, inner_joints, position_columns, skeleton_scale
from mocapz.codecs.pga.model import PGAModel
from mocapz.codecs.pga.outliers import decode_outliers, kept_frames
from mocapz.codecs.pga.packing import once, split_streams
from mocapz.codecs.pga.params import PGASettings
from mocapz.codecs.pga.quantise import dequantise_model, model_from_matrices
from mocapz.errors import FormatError, OptionError
from mocapz.format.entropy import decode_int_matrix
from mocapz.model.header import ClipHeader
from mocapz.model.kinematics import content_key
from mocapz.model.skeleton import Skeleton


def stream_count(s: PGASettings, n_other: int) -> int:
    """Number of matrices in the ``data`` section, in the order :func:`mocapz.codecs.pga.encode.encode_prepared`
    packs them: model header, loadings, root position, root orientation, effectors, then the coordinates
    (when coded) and the ``n_other`` non-root position channels (when any)."""
    return 5 + int(s.use_coords) + int(n_other > 0)


def decode(sections: dict[str, bytes], header: ClipHeader) -> Any:
    """Container entry point: sections -> Motion."""
    skeleton, settings = _checked(sections, header)
    try:
        channels = decode_channels(skeleton, settings, sections, header.frames)
    except KeyError as exc:
        raise FormatError(None, f"corrupted PGA stream (missing section {exc})") from None
    return _motion(header, channels)


def decode_window(sections: dict[str, bytes], header: ClipHeader, start: int, stop: int,
                  memo: dict[str, Any] | None = None) -> Any:
    """Frames ``[start, stop)`` of a clip: every stream decoded, the IK solved on those frames only (the values
    of a full decode, to the bit: the compiled IK and Euler angles go frame by frame); None where the full
    decode is needed: a file without ``turns``, the temporal regulariser coupling the frames, or no compiled
    kernels (NumPy's batched products sum a frame's values in an order that depends on the batch). ``memo``: a
    dict kept for these sections (a reader's), where the first window leaves the decoded streams."""
    skeleton, s = _checked(sections, header)
    if s.lam_temporal > 0 or turns.SECTION not in sections \
            or ikjit.kernels(header.frames - len(s.outliers)) is None:
        return None
    frames = header.frames
    try:
        out = np.zeros((stop - start, skeleton.n_channels))
        _check_outliers(s, frames)
        outliers = np.asarray(s.outliers, dtype=np.int64)
        inside = (outliers >= start) & (outliers < stop)
        if inside.any():  # the outlier frames' exact values are decoded whole (a few frames)
            exact = decode_outliers(sections["outl"], outliers.size, skeleton.n_channels)
            out[outliers[inside] - start] = exact[inside]
        # the kept frames' indices: frame f (not an outlier) is kept frame f - (outliers before f)
        lo, hi = np.array([start, stop]) - np.searchsorted(outliers, [start, stop])
        if hi > lo:
            rows = np.setdiff1d(np.arange(start, stop), outliers) - start
            out[rows] = decode_span(skeleton, s, sections, frames - outliers.size, int(lo), int(hi), memo)
    except KeyError as exc:
        raise FormatError(None, f"corrupted PGA stream (missing section {exc})") from None
    return _motion(replace(header, frames=stop - start), out)


def _checked(sections: dict[str, bytes], header: ClipHeader) -> tuple[Skeleton, PGASettings]:
    """The file's skeleton and settings, checked against the header (FormatError)."""
    skeleton = header.skeleton
    if skeleton is None:
        raise FormatError(None, "corrupted PGA stream (marker layout)")
    try:
        check_skeleton(skeleton)
    except OptionError as exc:
        raise FormatError(None, f"corrupted PGA stream ({exc.message})") from None
    try:
        settings = PGASettings.from_bytes(sections["params"])
    except KeyError as exc:
        raise FormatError(None, f"corrupted PGA stream (missing section {exc})") from None
    # the settings drive the kept frames only (a 0-frame clip keeps defaults)
    if header.frames > len(settings.outliers):
        settings.check_decoded(3 * len(inner_joints(skeleton)), skeleton.n_points)
    return skeleton, settings


def _motion(header: ClipHeader, channels: np.ndarray) -> Any:
    motion = header.motion(channels)
    # lossy values: write them with the source's finest precision (at least 4 decimals) in every column,
    # not with per-column counts that fit the source's values only (a constant column may have 0)
    if motion.decimals is not None:
        motion.decimals = np.full_like(motion.decimals, max(4, int(motion.decimals.max(initial=0))))
    return motion


def _check_outliers(s: PGASettings, frames: int) -> None:
    if any(not 0 <= f < frames for f in s.outliers) or any(b <= a for a, b in pairwise(s.outliers)):
        raise FormatError(None, "corrupted PGA stream (outlier frames)")


def decode_channels(skeleton: Skeleton, s: PGASettings, sections: dict[str, bytes], frames: int,
                    edit: dict[int, np.ndarray] | None = None, memo: dict[Hashable, Any] | None = None) -> np.ndarray:
    """Decoded channel values ``(frames, channels)``.

    ``edit`` maps effector slots to replacement global trajectories ``(kept frames, 3)`` (motion editing);
    ``memo``: a rate search's (:func:`decode_streams`).
    """
    _check_outliers(s, frames)
    outliers = np.asarray(s.outliers, dtype=np.int64)
    n = frames - outliers.size
    # every stream is read, and checked against the frame count, before frames x channels are allocated
    exact = decode_outliers(sections["outl"], outliers.size, skeleton.n_channels) if outliers.size else None
    kept_values = decode_kept(skeleton, s, sections, n, edit, memo=memo) if n else None
    if exact is None and kept_values is not None and kept_values.shape == (frames, skeleton.n_channels):
        return kept_values  # every frame kept: no copy
    out = np.zeros((frames, skeleton.n_channels))
    if kept_values is not None:
        out[kept_frames(frames, outliers)] = kept_values
    if exact is not None:
        out[outliers] = exact
    return out


@dataclass
class Decoded:
    """The decoded streams of the kept frames (F = kept frames)."""

    model: PGAModel
    effectors: np.ndarray
    problem: IKProblem
    root_pos: np.ndarray  # (F, 3)
    root_rot: np.ndarray  # (F, 3, 3)
    targets: np.ndarray  # (F, e, 3) effector targets in the root frame
    coords: np.ndarray | None  # (F, k)
    other: np.ndarray  # (F, p) decoded position channels of non-root joints


def decode_streams(skeleton: Skeleton, s: PGASettings, sections: dict[str, bytes], n: int,
                   window: tuple[int, int] | None = None, memo: dict[Hashable, Any] | None = None) -> Decoded:
    """The ``data`` section's streams for ``n`` kept frames, with the effector targets in the root frame; only
    the kept frames ``[a, b)`` of ``window`` (those rows of the whole, to the bit; the trajectories' samples they
    do not need are not computed). ``memo``: a rate search's (:func:`.packing.once`), where each stream's
    decoding is kept by its bytes and settings (whole clips only)."""
    inner = inner_joints(skeleton)
    _, other_cols = position_columns(skeleton)
    if s.eff_mode == 2:
        effectors = np.zeros(0, dtype=np.int64)
    else:
        effectors = effector_points(skeleton, s.effectors)
    memo = memo if window is None else None
    blobs = split_streams(sections["data"], stream_count(s, other_cols.size))
    mats = [once(memo, ("integers", b), lambda b=b: decode_int_matrix(b)) for b in blobs]
    _check_shapes(mats, s, n, len(inner), len(effectors), other_cols.size)
    model = once(memo, ("model", blobs[0], blobs[1], s.k, s.basis_bits, s.mean_step), lambda: dequantise_model(
        model_from_matrices(mats[0], mats[1]), inner, s.k, s.basis_bits, s.mean_step))
    if window is None:
        rn, so3, f = lifting.decode_rn, lifting.decode_so3, n
    else:
        rn = functools.partial(lifting.decode_rn_window, a=window[0], b=window[1])
        so3 = functools.partial(lifting.decode_so3_window, a=window[0], b=window[1])
        f = window[1] - window[0]

    def decoded(i: int, step: float, lod: int, of: Callable[..., np.ndarray] = rn) -> np.ndarray:
        return once(memo, (i, blobs[i], step, lod), lambda: of(mats[i], n, step, lod))

    root_pos = decoded(2, s.pos_step, s.lod_root)
    root_rot = decoded(3, s.rot_step, s.lod_root, so3)
    if s.eff_mode == 2:
        eff = np.zeros((f, 0, 3))
    else:
        eff = decoded(4, s.pos_step, s.lod_effectors).reshape(f, -1, 3)
    if eff.shape[1] != len(effectors):
        raise FormatError(None, "corrupted PGA stream (effector count)")
    pos = 5
    coords = None
    if s.use_coords:
        coords = decoded(pos, s.coord_step, s.lod_coords)
        pos += 1
    other = decoded(pos, s.pos_step, 0) if other_cols.size else np.zeros((f, 0))
    problem = make_problem(skeleton, model, effectors, other,
                           once(memo, ("skeleton scale",), lambda: skeleton_scale(skeleton)))
    if s.eff_mode == 1 and coords is not None:  # the coded pose's effectors, kept by what they are a function of
        coded = once(memo, ("decoded pose's effectors", *blobs[:2], s.k, s.basis_bits, s.mean_step, effectors.tobytes(),
                            blobs[5], s.coord_step, s.lod_coords, *((blobs[6], s.pos_step) if other_cols.size else ())),
                     lambda: problem.forward(coords)[0])
        targets = coded + eff
    else:
        targets = targets_in_root_frame(eff, root_pos, root_rot)
    return Decoded(model, effectors, problem, root_pos, root_rot, targets, coords, other)


def _check_shapes(mats: list[np.ndarray], s: PGASettings, n: int, inner: int, effectors: int, other: int) -> None:
    """FormatError unless the decoded integer matrices have the shapes the settings and ``n`` kept frames give."""
    def rows(lod: int) -> int:
        return lifting.coefficient_rows(n, lod)

    head = (4 * inner + s.k, 1)
    moving = int(np.count_nonzero(mats[0][:inner])) if mats[0].shape == head else 0
    expected = [("model", head), ("model loadings", (3 * moving, s.k)), ("root positions", (rows(s.lod_root), 3)),
                ("root rotations", (rows(s.lod_root), 3)),
                ("end effectors", mats[4].shape if s.eff_mode == 2 else (rows(s.lod_effectors), 3 * effectors))]
    if s.use_coords:
        expected.append(("coordinates", (rows(s.lod_coords), s.k)))
    if other:
        expected.append(("position channels", (rows(0), other)))
    for m, (what, shape) in zip(mats, expected, strict=True):
        if m.shape != shape:
            raise FormatError(None, f"corrupted PGA stream ({what}: shape {m.shape} where {shape} is expected)")


def decode_rows(skeleton: Skeleton, s: PGASettings, sections: dict[str, bytes], n: int,
                rows: np.ndarray, memo: dict[Hashable, Any] | None = None) -> np.ndarray:
    """Channels ``(len(rows), C)`` of some kept frames only (the IK is per frame when the temporal
    regulariser is off, so this equals those rows of the full decode; rate control uses it to check
    candidates quickly; ``memo``: its, :func:`decode_streams`)."""
    d = decode_streams(skeleton, s, sections, n, memo=memo)
    if s.lam_temporal > 0:
        return rebuild(skeleton, d, s, d.targets)[rows]
    sub = _rows_of(d, rows)
    return rebuild(skeleton, sub, s, sub.targets, frames=n)  # the whole clip's path: its rows' values


def decode_span(skeleton: Skeleton, s: PGASettings, sections: dict[str, bytes], n: int, lo: int, hi: int,
                memo: dict[str, Any] | None = None) -> np.ndarray:
    """Channels ``(hi - lo, C)`` of the kept frames ``[lo, hi)`` of a file with a ``turns`` section and no
    temporal regulariser: those rows of :func:`decode_kept`, to the bit (every stream decoded, the IK solved on
    those frames only, on the whole clip's path, the stored turns unwrapping them). ``memo``: a reader's, where
    the streams are kept decoded whole (the first window decodes them) and later windows take their rows."""
    if memo is None:
        sub = decode_streams(skeleton, s, sections, n, (lo, hi))
    else:
        if "pga streams" not in memo:
            memo["pga streams"] = decode_streams(skeleton, s, sections, n)
        sub = _rows_of(memo["pga streams"], slice(lo, hi))
    return rebuild(skeleton, sub, s, sub.targets, frames=n, unwrap=stored_turns(skeleton, sections, n, lo))


def _rows_of(d: Decoded, rows: np.ndarray | slice) -> Decoded:
    """The decoded streams of some kept frames only (their IK problem with them)."""
    trans = d.problem.trans[rows] if d.problem.trans.ndim == 3 else d.problem.trans
    problem = IKProblem(d.problem.skeleton, d.model, d.effectors, d.problem.rest_rot, trans, d.problem.scale)
    return Decoded(d.model, d.effectors, problem, d.root_pos[rows], d.root_rot[rows], d.targets[rows],
                   None if d.coords is None else d.coords[rows], d.other[rows])


def decode_kept(skeleton: Skeleton, s: PGASettings, sections: dict[str, bytes], n: int,
                edit: dict[int, np.ndarray] | None = None, unwrap: Unwrapper | None = None,
                memo: dict[Hashable, Any] | None = None, leave: bool = False) -> np.ndarray:
    """Channels ``(n, C)`` of the ``n`` kept frames; ``edit`` as in :func:`decode_channels`; ``unwrap``: the
    file's stored turns (:mod:`.turns`) by default, else np.unwrap (edited targets: np.unwrap); ``memo``: a rate
    search's (:func:`decode_streams`). ``leave``: this thread's next decode of the same sections (an encoder's
    of its own file: :func:`with_turns`, then the correction's base) takes their Euler angles as they are, not
    decoding them again (the same numbers); any decode takes what was left, or drops it."""
    if not edit and unwrap is None:
        unwrap = stored_turns(skeleton, sections, n)
    key = None if edit or memo is not None else _angles_key(skeleton, sections, n)
    left = _LEFT.__dict__.pop("angles", None)
    if key is not None and left is not None and left[0] == key:  # what with_turns decoded of these sections
        return finish_channels(skeleton, *left[1:], unwrap)
    d = decode_streams(skeleton, s, sections, n, memo=memo)
    targets = d.targets
    if edit:
        targets = targets.copy()
        for slot, traj in edit.items():
            targets[:, slot] = targets_in_root_frame(traj[:, None], d.root_pos, d.root_rot)[:, 0]
    angles = euler_angles(skeleton, d, s, targets)
    if leave and key is not None:
        _LEFT.angles = (key, angles.copy(), d.root_pos, d.other)
    return finish_channels(skeleton, angles, d.root_pos, d.other, unwrap)


_LEFT = threading.local()  # ``angles``: the Euler angles of the sections with_turns decoded last, for the next decode


def _angles_key(skeleton: Skeleton, sections: dict[str, bytes], n: int) -> tuple[Any, ...]:
    """What a clip's Euler angles before unwrapping are a function of: its skeleton, kept frames and sections
    (but the ``turns`` its unwrapping reads)."""
    return content_key(skeleton), n, tuple(sorted((k, v) for k, v in sections.items() if k != turns.SECTION))


def stored_turns(skeleton: Skeleton, sections: dict[str, bytes], n: int, first: int = 0) -> Unwrapper | None:
    """The unwrapper of the file's ``turns`` section for kept frames from ``first`` (None: the file has none)."""
    if turns.SECTION not in sections:
        return None
    return turns.Turns.from_bytes(sections[turns.SECTION], n, skeleton.rotation_columns()).unwrapper(first)


def with_turns(skeleton: Skeleton, sections: dict[str, bytes], frames: int) -> dict[str, bytes]:
    """An encoder's final sections of a clip of ``frames`` frames, with its ``turns`` section where the clip is
    coded with the seekable layout (the events of the angles the decoder's IK gives, :mod:`.turns`)."""
    if not seekable(frames) or turns.SECTION in sections:
        return sections
    s = PGASettings.from_bytes(sections["params"])
    n = frames - len(s.outliers)
    raw = decode_kept(skeleton, s, sections, n, unwrap=turns.raw, leave=True) if n \
        else np.zeros((0, skeleton.n_channels))
    events = turns.Turns.of(raw, skeleton.rotation_columns(), 360.0 if skeleton.angle_unit == "deg" else 2 * np.pi)
    return {**sections, turns.SECTION: events.to_bytes()}


def rebuild(skeleton: Skeleton, d: Decoded, s: PGASettings, targets: np.ndarray,
            frames: int | None = None, unwrap: Unwrapper | None = None) -> np.ndarray:
    """IK and channel assembly for the kept frames. Always returns finite values. ``frames``: the kept frames
    of the clip ``d`` is taken from (None: ``d``'s), which picks the compiled or the NumPy path
    (:func:`ikjit.kernels`); ``unwrap``: how the angles are unwrapped (:func:`.channels.finish_channels`)."""
    return finish_channels(skeleton, euler_angles(skeleton, d, s, targets, frames), d.root_pos, d.other, unwrap)


def euler_angles(skeleton: Skeleton, d: Decoded, s: PGASettings, targets: np.ndarray,
                 frames: int | None = None) -> np.ndarray:
    """:func:`rebuild`'s channels ``(kept frames, C)`` before :func:`.channels.finish_channels`: the Euler
    angles of the IK's poses (not unwrapped), zero in the position columns."""
    n = d.root_pos.shape[0]
    clip = n if frames is None else frames
    model = d.model
    x0 = d.coords if d.coords is not None else np.zeros((n, model.k))
    if len(d.effectors) == 0 or s.iterations == 0:
        x = x0
    else:
        x = solve_fast(d.problem, targets, x0, x_prior=d.coords, lam_temporal=s.lam_temporal,
                       lam_prior=s.lam_prior if d.coords is not None else 0.0, iterations=s.iterations,
                       frames=clip)
    if not np.isfinite(x).all():  # pragma: no cover - solve() keeps finite values
        x = np.nan_to_num(x0)
    jit = ikjit.kernels(clip)
    tables = euler_tables(skeleton, model.joints) if jit is not None else None
    if tables is not None and jit is not None:  # the compiled path: the pose's Euler angles in one pass
        out = np.zeros((n, skeleton.n_channels))
        bad = jit["euler_channels"](np.ascontiguousarray(x, dtype=np.float64),
                                    np.ascontiguousarray(model.basis.T, dtype=np.float64),
                                    np.ascontiguousarray(model.mean, dtype=np.float64),
                                    np.ascontiguousarray(d.root_rot, dtype=np.float64), *tables,
                                    180.0 / np.pi if skeleton.angle_unit == "deg" else 1.0, out)
        if bad:
            raise FormatError(None, "corrupted PGA stream (poses out of range)")
        return out
    local = np.broadcast_to(np.eye(3), (n, skeleton.n_joints, 3, 3)).copy()
    local[:, 0] = d.root_rot
    local[:, model.joints] = pose(model, x, clip)
    if not np.isfinite(local).all():  # only damaged streams (huge steps, loadings or coordinates) get here
        raise FormatError(None, "corrupted PGA stream (poses out of range)")
    out = np.zeros((n, skeleton.n_channels))
    channels_from_rotations(skeleton, local, out)
    return out
