"""The error and size figures of ``../shared/METRICS.md``, for skeletal and marker data.

Errors are measured on global 3D positions: for skeletons, every joint and end site computed by forward
kinematics with the ORIGINAL skeleton from the original and the decoded channels; for markers, the marker
positions, leaving out samples missing in the original.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from mocapz import _jit, aot
from mocapz.errors import MocapzError
from mocapz.metrics.chunks import CHUNK_FRAMES, frame_chunks  # noqa: F401 (re-exported)
from mocapz.metrics.contacts import find_contacts, foot_points, up_axis  # noqa: F401 (re-exported)
from mocapz.metrics.skate import foot_skates, jitter_pct
from mocapz.model.motion import AnyMotion, MarkerMotion, Motion


@dataclass
class ErrorReport:
    """Error figures. Lengths in the file's unit; ``*_cm`` in centimetres where the unit is known.

    ``foot_skate`` (frame to frame) and ``foot_skate_window`` (over 0.1 s windows) are in file units per
    second, ``jitter_pct`` in percent of the original's acceleration energy (:mod:`mocapz.metrics.skate`).
    """

    distortion_pct: float
    arms: float
    max_err: float
    p99_err: float
    bone_len_err: float
    foot_skate: float | None
    unit_cm: float | None
    frames: int
    points: int
    foot_skate_window: float | None = None
    jitter_pct: float | None = None

    def _cm(self, v: float | None) -> float | None:
        return None if v is None or self.unit_cm is None else v * self.unit_cm

    @property
    def arms_cm(self) -> float | None:
        return self._cm(self.arms)

    @property
    def max_err_cm(self) -> float | None:
        return self._cm(self.max_err)

    @property
    def p99_err_cm(self) -> float | None:
        return self._cm(self.p99_err)

    def as_dict(self) -> dict[str, float | int | None]:
        d = asdict(self)
        d.update(arms_cm=self.arms_cm, max_err_cm=self.max_err_cm, p99_err_cm=self.p99_err_cm,
                 foot_skate_cm_per_s=self._cm(self.foot_skate),
                 foot_skate_window_cm_per_s=self._cm(self.foot_skate_window))
        return d


def positions_pair(original: AnyMotion, decoded: AnyMotion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Original and decoded positions ``(frames, points, 3)`` and a validity mask ``(frames, points)``."""
    if isinstance(original, Motion) and isinstance(decoded, Motion):
        from mocapz.model.kinematics import forward_positions

        if decoded.n_frames != original.n_frames:
            raise MocapzError(
                f"decoded motion has shape ({decoded.n_frames} frames), original {original.n_frames} frames"
            )
        a = forward_positions(original.skeleton, original.channels)
        if decoded.skeleton.channel_labels() == original.skeleton.channel_labels():
            # METRICS.md: the decoded channels through the ORIGINAL skeleton
            b = forward_positions(original.skeleton, decoded.channels)
        else:
            # another layout of the same skeleton (e.g. an .amc written from a .bvh): match points by name
            names = decoded.skeleton.point_names
            names[0] = original.skeleton.point_names[0]  # roots correspond whatever their names (AMC "root")
            missing = [n for n in original.skeleton.point_names if n not in names]
            if missing:
                raise MocapzError(
                    "decoded motion has a different skeleton (missing points: " + ", ".join(missing[:5]) + ")"
                )
            full = forward_positions(decoded.skeleton, decoded.channels)
            b = full[:, [names.index(n) for n in original.skeleton.point_names]]
        return a, b, np.ones(a.shape[:2], dtype=bool)
    if isinstance(original, MarkerMotion) and isinstance(decoded, MarkerMotion):
        if decoded.positions.shape != original.positions.shape:
            raise MocapzError(
                f"decoded markers have shape {decoded.positions.shape}, original {original.positions.shape}"
            )
        valid = ~original.missing
        return original.positions, decoded.positions, valid
    raise MocapzError("cannot compare skeletal data with marker data")


PAIR_VALUES = 1 << 21  # differences (frames x rows x points x 3) made at a time by pair_distances: 16 MB of float64


def distortion_pct(a: np.ndarray, b: np.ndarray, valid: np.ndarray | None = None) -> float:
    """Karni-Gotsman ``100 ||A - B||_F / ||A - E(A)||_F`` with ``E(A)`` the per-point temporal mean (positions
    ``(frames, points, 3)``, ``valid`` ``(frames, points)`` present samples, default all). With every sample
    present and C-ordered positions, each sum is over one array of squares made in place (one ``(frames,
    points, 3)`` temporary in all; the same numbers as the copies made otherwise)."""
    if (valid is None or valid.all()) and a.flags.c_contiguous and b.flags.c_contiguous:
        dev = a - a.sum(axis=0) / max(a.shape[0], 1)
        den = np.sqrt(np.square(dev, out=dev).sum())
        num = np.sqrt(np.square(np.subtract(a, b, out=dev), out=dev).sum())
    else:
        valid = np.ones(a.shape[:2], dtype=bool) if valid is None else valid
        w = valid[..., None]
        a0 = np.where(w, a, 0.0)
        b0 = np.where(w, b, 0.0)
        mean = a0.sum(axis=0) / np.maximum(valid.sum(axis=0), 1)[:, None]
        den = np.sqrt((np.where(w, a0 - mean, 0.0) ** 2).sum())
        num = np.sqrt(((a0 - b0) ** 2).sum())
    return float(100.0 * num / den) if den > 0 else (0.0 if num == 0 else float("inf"))


def point_errors(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean error per frame and point, ``(frames, points)``, of positions ``a`` and ``b`` ``(frames, points,
    3)``; :data:`CHUNK_FRAMES` frames at a time (the same numbers, without a whole clip's difference)."""
    out = np.empty(a.shape[:-1])
    if (kern := _err_kernel(a, b)) is not None:  # compiled ahead of time: the same numbers in one pass
        kern.point_errors(a, b, out)
        return out
    for part in frame_chunks(a.shape[0]):
        out[part] = np.linalg.norm(a[part] - b[part], axis=-1)
    return out


def _err_kernel(a: np.ndarray, b: np.ndarray) -> Any:
    """:mod:`.errkernels` from the extension built ahead of time, for float64 positions of one shape; else None."""
    if not (type(a) is np.ndarray and type(b) is np.ndarray and a.dtype == b.dtype == np.float64
            and a.shape == b.shape and a.ndim == 3 and a.shape[-1] == 3 and _jit.enabled()):
        return None
    return aot.kernels("err")


def arms(err: np.ndarray, valid: np.ndarray) -> float:
    """Pattern paper eq. 3: mean over frames of the RMS over (valid) points."""
    sq = np.where(valid, err, 0.0) ** 2
    n = valid.sum(axis=1)
    ok = n > 0
    return float(np.mean(np.sqrt(sq[ok].sum(axis=1) / n[ok]))) if ok.any() else 0.0


def pair_distances(points: np.ndarray) -> Iterator[tuple[slice, np.ndarray]]:
    """The distances between every two points of ``points`` ``(frames, M, 3)``, a few rows at a time (no frames x
    M x M x 3 array: :data:`PAIR_VALUES`): ``(rows, d)`` with ``d`` ``(frames, rows, M)`` (NaN where either is
    missing)."""
    frames, m = points.shape[:2]
    step = max(1, PAIR_VALUES // max(frames * m * 3, 1))
    for a in range(0, m, step):
        yield slice(a, a + step), np.linalg.norm(points[:, a:a + step, None] - points[:, None, :], axis=-1)


def bone_pairs(motion: AnyMotion) -> np.ndarray:
    """``(pairs, 2)`` point indices whose distance is a bone length.

    Skeletons: every point with its parent (zero-length bones skipped). Markers: each marker with its
    most rigid neighbour (the partner whose distance varies least over the clip).
    """
    if isinstance(motion, Motion):
        sk = motion.skeleton
        parents = sk.point_parents
        pts = np.flatnonzero(parents >= 0)
        lengths = np.linalg.norm(
            np.concatenate([sk.offsets, np.array([o for _, o, _ in sk.end_sites]).reshape(-1, 3)])[pts], axis=1
        )
        pts = pts[lengths > 1e-9]
        return np.stack([pts, parents[pts]], axis=1)
    pos = motion.positions
    m = pos.shape[1]
    if m < 2:
        return np.zeros((0, 2), dtype=np.int64)
    step = max(1, pos.shape[0] // 500)
    sub = pos[::step]
    spread = np.empty((m, m))
    for rows, d in pair_distances(sub):
        with np.errstate(invalid="ignore"):
            mean = np.nanmean(d, axis=0)
            spread[rows] = np.nanstd(d, axis=0) / np.maximum(mean, 1e-9)
    spread[np.isnan(spread)] = np.inf
    np.fill_diagonal(spread, np.inf)
    partner = np.argmin(spread, axis=1)
    pairs = {tuple(sorted((i, int(partner[i])))) for i in range(m) if np.isfinite(spread[i, partner[i]])}
    return np.array(sorted(pairs), dtype=np.int64).reshape(-1, 2)


def bone_len_err(a: np.ndarray, b: np.ndarray, valid: np.ndarray, pairs: np.ndarray) -> float:
    """Max over frames and bones of ``|len_decoded - len_original| / len_original``."""
    if len(pairs) == 0:
        return 0.0
    worst = []  # each chunk of frames' largest: the largest of them is the whole clip's
    for t in frame_chunks(a.shape[0]):
        la = np.linalg.norm(a[t, pairs[:, 0]] - a[t, pairs[:, 1]], axis=-1)
        lb = np.linalg.norm(b[t, pairs[:, 0]] - b[t, pairs[:, 1]], axis=-1)
        ok = valid[t, pairs[:, 0]] & valid[t, pairs[:, 1]] & (la > 1e-9)
        if ok.any():
            worst.append(np.max(np.abs(lb - la)[ok] / la[ok]))
    return float(np.max(worst)) if worst else 0.0


def foot_skate(motion: AnyMotion, a: np.ndarray, b: np.ndarray, valid: np.ndarray,
               unit_cm: float | None) -> float | None:
    """Decoded minus original mean horizontal foot speed over contact frames, file units per second
    (contacts: :func:`mocapz.metrics.contacts.find_contacts`; frame to frame, see
    :mod:`mocapz.metrics.skate`)."""
    return foot_skates(motion, a, b, valid, unit_cm)[0]


def exact_copy(original: AnyMotion, decoded: AnyMotion) -> ErrorReport | None:
    """The position error figures of a decoded motion that holds every value of the original, bit for bit, in
    its layout (a lossless round trip: its positions are the original's, every error zero), found without
    computing positions; None where any value, the layout or the kind differs (then :func:`evaluate`). Foot
    skate and jitter are not measured (None)."""
    if isinstance(original, Motion) and isinstance(decoded, Motion):
        same = decoded.skeleton.channel_labels() == original.skeleton.channel_labels() \
            and np.array_equal(decoded.channels, original.channels)
        points = original.skeleton.n_points
    elif isinstance(original, MarkerMotion) and isinstance(decoded, MarkerMotion):
        same = np.array_equal(decoded.positions, original.positions, equal_nan=True)
        points = original.n_markers
    else:
        return None
    if not same:
        return None
    unit_cm = original.skeleton.unit_cm if isinstance(original, Motion) else original.unit_cm
    return ErrorReport(distortion_pct=0.0, arms=0.0, max_err=0.0, p99_err=0.0, bone_len_err=0.0, foot_skate=None,
                       unit_cm=unit_cm, frames=original.n_frames, points=points)


def evaluate(original: AnyMotion, decoded: AnyMotion) -> ErrorReport:
    """All error figures of METRICS.md for a decoded motion against its original."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # markers never observed: empty means, NaN skipped
        return _evaluate(original, decoded)


def _evaluate(original: AnyMotion, decoded: AnyMotion) -> ErrorReport:
    a, b, valid = positions_pair(original, decoded)
    if isinstance(decoded, MarkerMotion):
        dec_missing = ~np.isfinite(b).all(axis=-1)
        if np.any(dec_missing & valid):
            raise MocapzError("decoded markers are missing samples the original has")
    err = point_errors(a, b)
    ev = err[valid]
    unit_cm = original.skeleton.unit_cm if isinstance(original, Motion) else original.unit_cm
    skate, skate_window = foot_skates(original, a, b, valid, unit_cm)
    return ErrorReport(
        distortion_pct=distortion_pct(a, b, valid),
        arms=arms(err, valid),
        max_err=float(ev.max()) if ev.size else 0.0,
        p99_err=float(np.percentile(ev, 99)) if ev.size else 0.0,
        bone_len_err=bone_len_err(a, b, valid, bone_pairs(original)),
        foot_skate=skate,
        unit_cm=unit_cm,
        frames=int(a.shape[0]),
        points=int(a.shape[1]),
        foot_skate_window=skate_window,
        jitter_pct=jitter_pct(a, b, valid),
    )


def size_figures(
    motion: AnyMotion, compressed_bytes: int, source_bytes: int | None = None
) -> dict[str, float | int | None]:
    """METRICS.md size figures: raw_bytes, compressed_bytes, ratio, ratio_file, bytes_per_second."""
    raw = motion.raw_bytes
    src = source_bytes if source_bytes is not None else motion.metadata.get("file_bytes")
    return {
        "raw_bytes": raw,
        "compressed_bytes": int(compressed_bytes),
        "ratio": raw / compressed_bytes if compressed_bytes else None,
        "ratio_file": (src / compressed_bytes) if (src and compressed_bytes) else None,
        "bytes_per_second": compressed_bytes / motion.duration if motion.duration else None,
    }
