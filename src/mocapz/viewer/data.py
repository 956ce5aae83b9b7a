"""What the viewer shows: positions of the original and decoded motions in a Z-up frame, per-point errors and
the clip's figures, prepared once for both the HTML page and the GIF / MP4 renderer.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.errors import MocapzError, OptionError
from mocapz.metrics.figures import bone_pairs, evaluate, point_errors, positions_pair, size_figures, up_axis
from mocapz.model.motion import AnyMotion, MarkerMotion, Motion

#: Point-frames (frames x points) above which the page shows every n-th frame only (about 4 MB of HTML).
PAGE_BUDGET = 250_000


@dataclass
class ViewData:
    """Everything drawn by the page and the animation renderer.

    Attributes:
        name: clip name.
        kind: ``"skeleton"`` or ``"markers"``.
        frame_rate: frames per second of ``original`` (the source rate divided by ``step``).
        step: source frames per shown frame (1 unless decimated).
        first_frame: source index of the first shown frame.
        source_frames: frames in the source clip.
        names: point names (joints then end sites, or marker labels).
        bones: ``(bones, 2)`` point index pairs drawn as segments (child, parent or marker links).
        original: ``(frames, points, 3)`` positions, Z up, file units; NaN where the original has a gap.
        decoded: same shape for the decoded motion, or ``None`` when only one motion is viewed.
        errors: ``(frames, points)`` error per point, NaN where invalid (``None`` without decoded); when
            decimated, the largest error over the source frames a shown frame stands for.
        unit: length label of the figures (``"cm"`` when the file unit is known, else ``"units"``).
        unit_scale: multiply file units by this to get ``unit``.
        floor: height of the ground plane (file units, Z up).
        height: typical body height (file units): sets the camera distance and point sizes.
        grid: ground grid spacing (file units): 1 m where the unit is known.
        center: ``(frames, 3)`` smoothed centroid of the original, for a camera that follows the body.
        figures: ``(label, text)`` pairs shown above the player.
        stats: raw figures (``evaluate`` and size figures) for scripts.
        decoded_label: caption of the decoded pane (e.g. ``"decoded (pga)"``).
        notes: remarks shown under the page (decimation, up axis...).
        color_scale: error shown fully red (file units) chosen by the user, else ``None`` (the clip's max).
    """

    name: str
    kind: str
    frame_rate: float
    step: int
    first_frame: int
    source_frames: int
    names: list[str]
    bones: np.ndarray
    original: np.ndarray
    decoded: np.ndarray | None
    errors: np.ndarray | None
    unit: str
    unit_scale: float
    floor: float
    height: float
    grid: float
    center: np.ndarray
    figures: list[tuple[str, str]]
    stats: dict[str, Any] = field(default_factory=dict)
    decoded_label: str = "decoded"
    notes: list[str] = field(default_factory=list)
    color_scale: float | None = None

    @property
    def n_frames(self) -> int:
        return int(self.original.shape[0])

    @property
    def n_points(self) -> int:
        return int(self.original.shape[1])

    @property
    def error_max(self) -> float:
        """Largest error over the shown frames (0 without decoded motion or errors)."""
        if self.errors is None or not np.isfinite(self.errors).any():
            return 0.0
        return float(np.nanmax(self.errors))

    def frame_error_stats(self) -> tuple[np.ndarray, np.ndarray]:
        """Per shown frame: largest and mean error over the valid points (zeros without errors)."""
        if self.errors is None:
            z = np.zeros(self.n_frames)
            return z, z
        ok = np.isfinite(self.errors)
        e0 = np.where(ok, self.errors, 0.0)
        n = ok.sum(axis=1)
        return e0.max(axis=1, initial=0.0), np.where(n > 0, e0.sum(axis=1) / np.maximum(n, 1), 0.0)


# ------------------------------------------------------------------------------------------------ loading
def load_motion(path: Path, asf: Path | None = None) -> tuple[AnyMotion, dict[str, Any]]:
    """Read a motion file or a ``.mcz`` (decoded); also return what is known of its compression.

    The second value holds ``compressed_bytes`` and ``codec`` for a ``.mcz``, else nothing.
    """
    from mocapz.files import open_motion

    opened = open_motion(path, asf)
    if opened.codec is None:
        return opened.motion, {}
    return opened.motion, {"compressed_bytes": opened.compressed_bytes, "codec": opened.codec}


# ---------------------------------------------------------------------------------------------- geometry
def to_z_up(a: np.ndarray, up: int) -> np.ndarray:
    """Rotate axes cyclically (keeping handedness) so that axis ``up`` becomes Z."""
    if up == 2:
        return a
    order = (2, 0, 1) if up == 1 else (1, 2, 0)
    return a[..., order]


def _unit_of(motion: AnyMotion) -> float | None:
    return motion.skeleton.unit_cm if isinstance(motion, Motion) else motion.unit_cm


def _smooth_center(a: np.ndarray, valid: np.ndarray, frame_rate: float) -> np.ndarray:
    """Centroid of the valid points per frame, gaps filled and smoothed over about 0.3 s."""
    w = valid[..., None]
    n = valid.sum(axis=1)
    c = np.where(w, a, 0.0).sum(axis=1) / np.maximum(n, 1)[:, None]
    ok = n > 0
    if not ok.any():
        return np.zeros((a.shape[0], 3))
    idx = np.arange(a.shape[0])
    c = np.stack([np.interp(idx, idx[ok], c[ok, k]) for k in range(3)], axis=1)
    half = max(0, int(round(0.15 * frame_rate)))
    if half and a.shape[0] > 1:
        pad = np.pad(c, ((half, half), (0, 0)), mode="edge")
        kernel = np.ones(2 * half + 1) / (2 * half + 1)
        c = np.stack([np.convolve(pad[:, k], kernel, mode="valid") for k in range(3)], axis=1)
    return c


def _nice_grid(height: float, unit_cm: float | None) -> float:
    if unit_cm:
        return 100.0 / unit_cm
    if height > 0:
        return 10.0 ** math.floor(math.log10(height / 2))
    return 1.0


# ------------------------------------------------------------------------------------------------ figures
def _fmt_len(v: float | None, unit_cm: float | None) -> str:
    if v is None or not math.isfinite(v):
        return "n/a"
    if unit_cm:
        return f"{v * unit_cm:.3g} cm"
    return f"{v:.4g} units"


def _figures(stats: dict[str, Any], n_frames: int, frame_rate: float, unit_cm: float | None,
             has_decoded: bool) -> list[tuple[str, str]]:
    figs: list[tuple[str, str]] = []
    if stats.get("codec"):
        figs.append(("codec", str(stats["codec"])))
    if stats.get("ratio") is not None:
        figs.append(("ratio", f"{stats['ratio']:.3g} : 1"))
    if stats.get("compressed_bytes") is not None:
        figs.append(("size", f"{stats['compressed_bytes']:,} B"))
    if has_decoded:
        figs.append(("distortion", f"{stats['distortion_pct']:.3g} %"))
        figs.append(("max error", _fmt_len(stats["max_err"], unit_cm)))
        figs.append(("p99 error", _fmt_len(stats["p99_err"], unit_cm)))
        figs.append(("ARMS", _fmt_len(stats["arms"], unit_cm)))
        figs.append(("bone length", f"{round(100 * stats['bone_len_err'], 6):.3g} %"))
        fs = stats.get("foot_skate")
        figs.append(("foot skate", "n/a" if fs is None else _fmt_len(fs, unit_cm) + "/s"))
        fw = stats.get("foot_skate_window")
        figs.append(("foot skate 0.1 s", "n/a" if fw is None else _fmt_len(fw, unit_cm) + "/s"))
        jit = stats.get("jitter_pct")
        figs.append(("jitter", "n/a" if jit is None or not math.isfinite(jit) else f"{jit:+.3g} %"))
    figs.append(("frames", f"{n_frames} @ {frame_rate:.4g} fps ({n_frames / frame_rate:.2f} s)"))
    return figs


# ------------------------------------------------------------------------------------------------ prepare
def prepare_view(original: AnyMotion, decoded: AnyMotion | None = None, *, compression: dict[str, Any] | None = None,
                 decoded_label: str | None = None, start: float | None = None, end: float | None = None,
                 budget: int | None = PAGE_BUDGET, color_scale: float | None = None) -> ViewData:
    """Positions, errors and figures of ``decoded`` against ``original`` for the viewer.

    Args:
        original: the reference motion.
        decoded: the motion to compare (decoded from a ``.mcz`` or read from a file), or ``None``.
        compression: ``{"compressed_bytes": n, "codec": name}`` when ``decoded`` came from a ``.mcz``:
            adds the size figures (ratio...).
        decoded_label: caption of the decoded pane (default ``"decoded"`` or ``"decoded (codec)"``).
        start, end: seconds of the clip to show (figures are always those of the whole clip).
        budget: largest ``frames * points`` shown; longer clips show every n-th frame (``None``: all).
        color_scale: error shown fully red, file units (default: the clip's largest error).

    Raises:
        MocapzError: the motions cannot be compared (different kinds, frame counts or skeletons).
    """
    compression = compression or {}
    unit_cm = _unit_of(original)
    if decoded is not None:
        a, b, valid = positions_pair(original, decoded)
        report = evaluate(original, decoded)
        stats: dict[str, Any] = dict(report.as_dict())
    else:
        a = original.positions() if isinstance(original, Motion) else original.positions
        b = None
        valid = np.ones(a.shape[:2], dtype=bool) if isinstance(original, Motion) else ~original.missing
        stats = {}
    if compression.get("compressed_bytes"):
        stats.update(size_figures(original, int(compression["compressed_bytes"])))
        stats["codec"] = compression.get("codec")
    n_src = int(a.shape[0])
    if n_src == 0 or a.shape[1] == 0:
        raise MocapzError(f"{original.name}: nothing to show (no frames or no points)")
    if not valid.any():
        raise MocapzError(f"{original.name}: every sample is missing")
    fps = float(original.frame_rate)
    figures = _figures(stats, n_src, fps, unit_cm, b is not None)

    # time range
    f0, f1 = 0, n_src
    if start is not None or end is not None:
        f0 = 0 if start is None else int(round(start * fps))
        f1 = n_src if end is None else int(round(end * fps))
        if (start is not None and start < 0) or f0 >= n_src or f1 <= f0:
            raise OptionError(f"time range {start}..{end} s is outside the clip (0..{n_src / fps:.3f} s) or empty")
        f1 = min(f1, n_src)

    up = up_axis(a, valid)
    a = to_z_up(np.where(valid[..., None], a, np.nan)[f0:f1], up)
    valid = valid[f0:f1]
    err = None
    if b is not None:
        err = np.where(valid, point_errors(np.nan_to_num(to_z_up(b[f0:f1], up)), np.nan_to_num(a)), np.nan)
        b = to_z_up(b[f0:f1], up)

    notes = [f"vertical axis of the file: {'XYZ'[up]} (shown upwards)"]
    n = f1 - f0
    step = 1
    if budget and n * a.shape[1] > budget:
        step = math.ceil(n * a.shape[1] / budget)
        notes.append(f"long clip: every {step}th frame is shown ({math.ceil(n / step)} of {n}); error colours show "
                     f"the largest error over the {step} frames each stands for")
    if start is not None or end is not None:
        notes.append(f"showing {f0 / fps:.3f}-{f1 / fps:.3f} s of {n_src / fps:.3f} s; figures are for the whole clip")
    if isinstance(original, MarkerMotion) and (~valid).any():
        notes.append(f"{100 * float((~valid).mean()):.1f} % of marker samples are missing in the original (gaps)")

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # frames where every marker is missing
        lows = np.nanmin(a[..., 2], axis=1)
        highs = np.nanmax(a[..., 2], axis=1)
    ok = np.isfinite(lows)
    floor = float(np.percentile(lows[ok], 2))
    height = float(np.median(highs[ok] - lows[ok]))
    if height <= 0:
        span = np.nanmax(a, axis=(0, 1)) - np.nanmin(a, axis=(0, 1))
        height = float(np.max(span)) or 1.0
    center = _smooth_center(np.nan_to_num(a), valid, fps)
    center[:, 2] = floor + 0.5 * height

    if step > 1:
        idx = np.arange(0, n, step)
        if err is not None:
            pad = (-n) % step
            e = np.pad(err, ((0, pad), (0, 0)), constant_values=np.nan).reshape(-1, step, err.shape[1])
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows (gaps) stay NaN
                err = np.nanmax(e, axis=1)
        a, center = a[idx], center[idx]
        b = None if b is None else b[idx]

    if isinstance(original, Motion):
        parents = original.skeleton.point_parents
        pts = np.flatnonzero(parents >= 0)
        bones = np.stack([pts, parents[pts]], axis=1) if len(pts) else np.zeros((0, 2), dtype=np.int64)
        names = original.skeleton.point_names
        kind = "skeleton"
    else:
        bones = bone_pairs(original)
        names = list(original.labels)
        kind = "markers"
    if decoded_label is None:
        decoded_label = f"decoded ({compression['codec']})" if compression.get("codec") else "decoded"
    return ViewData(
        name=original.name, kind=kind, frame_rate=fps / step, step=step, first_frame=f0, source_frames=n_src,
        names=list(names), bones=np.asarray(bones, dtype=np.int64).reshape(-1, 2), original=a, decoded=b,
        errors=err, unit="cm" if unit_cm else "units", unit_scale=unit_cm or 1.0, floor=floor, height=height,
        grid=_nice_grid(height, unit_cm), center=center, figures=figures, stats=stats,
        decoded_label=decoded_label, notes=notes, color_scale=color_scale,
    )


# ------------------------------------------------------------------------------------------------- camera
def default_yaw(view: ViewData) -> float:
    """Camera azimuth (radians) of a three-quarter side view.

    The side is taken across the main direction of travel, or, for a clip that stays in place, across the
    body's widest horizontal axis (shoulders / arms), so the limbs do not hide one another.
    """
    c = view.center[:, :2]
    travel = c - c.mean(axis=0)
    if np.ptp(c, axis=0).max(initial=0.0) > 0.5 * view.height:
        axis = np.linalg.svd(travel, full_matrices=False)[2][0]
        side = math.atan2(axis[1], axis[0]) + math.pi / 2
    else:
        mid = view.original[view.n_frames // 2]
        ok = np.isfinite(mid).all(axis=1)
        pts = mid[ok, :2] - mid[ok, :2].mean(axis=0) if ok.sum() >= 2 else np.zeros((2, 2))
        if np.abs(pts).max(initial=0.0) > 0:
            axis = np.linalg.svd(pts, full_matrices=False)[2][0]
            side = math.atan2(axis[1], axis[0])
        else:
            side = 0.0
        side += math.pi / 2
    return float(side - math.radians(35.0))


def color_scales(view: ViewData) -> list[tuple[str, float]]:
    """Error colour scales offered by the page: ``(label, file units)``, the default first (red at and above it)."""
    emax = view.error_max
    out: list[tuple[str, float]] = []
    if view.color_scale is not None:
        out.append((f"{_fmt_len(view.color_scale, view.unit_scale if view.unit == 'cm' else None)} (chosen)",
                    view.color_scale))
    if view.unit == "cm":
        out.append((f"clip max ({emax * view.unit_scale:.3g} cm)", emax))
        out += [(f"{v:g} cm", v / view.unit_scale) for v in (0.5, 1, 2, 5, 10, 20)]
    else:
        out.append((f"clip max ({emax:.3g} units)", emax))
        out += [(f"{v:g} % of body height", v / 100 * view.height) for v in (0.25, 0.5, 1, 2, 5, 10)]
    return out
