"""Error plots of a decoded motion against its original (``mocapz eval --plot errors.png``).

One image, three panels (matplotlib, Agg backend, no display needed):

* the largest and the RMS error of every point (joints and end sites in hierarchy order, or markers);
* the error over time: largest, 99th percentile and mean over the points of each frame;
* the error of every point over time as a heat map.

Errors are METRICS.md position errors (``mocapz.metrics.figures.positions_pair``), in centimetres where the file's
unit is known; samples missing in the original (marker gaps) are left out.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.errors import MocapzError, OptionError
from mocapz.io.common import atomic_write
from mocapz.metrics.figures import evaluate, point_errors, positions_pair
from mocapz.model.motion import AnyMotion, Motion

PLOT_SUFFIXES = (".png", ".svg", ".pdf")


def error_table(original: AnyMotion, decoded: AnyMotion) -> tuple[np.ndarray, list[str]]:
    """Per frame and point position error ``(frames, points)`` (NaN where the original is missing) and names."""
    a, b, valid = positions_pair(original, decoded)
    err = np.where(valid, point_errors(np.nan_to_num(a), np.nan_to_num(b)), np.nan)
    names = original.skeleton.point_names if isinstance(original, Motion) else list(original.labels)
    return err, names


def plot_errors(original: AnyMotion, decoded: AnyMotion, path: str | Path, *, force: bool = False,
                compressed_bytes: int | None = None, title: str | None = None) -> Path:
    """Write per-point and over-time error plots of ``decoded`` against ``original`` to ``path``.

    Args:
        original, decoded: the motions (decoded from a ``.mcz`` or read from a file).
        path: ``.png`` (default kind), ``.svg`` or ``.pdf``; written atomically.
        force: overwrite an existing file.
        compressed_bytes: size of the ``.mcz``, to show the compression ratio in the title.
        title: first title line (default: the clip name).

    Raises:
        MocapzError: the motions cannot be compared, or ``path`` exists (without ``force``) or has an
            unsupported extension.
    """
    path = Path(path)
    fmt = path.suffix.lower()
    if fmt not in PLOT_SUFFIXES:
        raise OptionError(f"{path}: plot must be {', '.join(PLOT_SUFFIXES)}, not {fmt or 'no extension'!r}")
    report = evaluate(original, decoded)
    err, names = error_table(original, decoded)
    unit_cm = report.unit_cm
    k, unit = (unit_cm, "cm") if unit_cm else (1.0, "file units")
    e = err * k
    frames, points = e.shape
    if frames == 0 or points == 0:
        raise MocapzError(f"{original.name}: nothing to plot (no frames or no points)")
    t = np.arange(frames) / original.frame_rate
    ok = np.isfinite(e)
    e0 = np.where(ok, e, 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # frames / points that are all gaps
        per_point_max = np.nanmax(e, axis=0)
        per_point_rms = np.sqrt(np.nanmean(e**2, axis=0))
        per_frame_max = np.nanmax(e, axis=1)
        per_frame_mean = np.nanmean(e, axis=1)
        per_frame_p99 = np.nanpercentile(e, 99, axis=1)

    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        raise MocapzError("error plots need matplotlib (pip install 'mocapz[plot]')") from None

    fig = Figure(figsize=(12, 9.5), dpi=90, layout="constrained")
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(3, 2, height_ratios=[1.15, 0.9, 1.0], width_ratios=[1, 0.018])
    ax_pts = fig.add_subplot(gs[0, 0])
    ax_time = fig.add_subplot(gs[1, 0])
    ax_heat = fig.add_subplot(gs[2, 0], sharex=ax_time)
    cax = fig.add_subplot(gs[2, 1])

    head = title or original.name
    figs = [f"distortion {report.distortion_pct:.3g} %", f"max {report.max_err * k:.3g} {unit}",
            f"p99 {report.p99_err * k:.3g} {unit}", f"ARMS {report.arms * k:.3g} {unit}"]
    if compressed_bytes:
        figs.insert(0, f"ratio {original.raw_bytes / compressed_bytes:.3g} : 1 ({compressed_bytes:,} B)")
    fig.suptitle(f"{head}: position error of the decoded motion\n" + "   \u00b7   ".join(figs), fontsize=11)

    # per point
    x = np.arange(points)
    ax_pts.bar(x, np.nan_to_num(per_point_max), width=0.8, color="#f4a582", label="largest")
    ax_pts.bar(x, np.nan_to_num(per_point_rms), width=0.5, color="#b2182b", label="RMS over time")
    step = max(1, int(np.ceil(points / 70)))
    ax_pts.set_xticks(x[::step])
    ax_pts.set_xticklabels([names[i] for i in x[::step]], rotation=90, fontsize=7)
    ax_pts.set_xlim(-0.6, points - 0.4)
    ax_pts.set_ylabel(f"error ({unit})")
    ax_pts.set_title("per point" + (" (joints and end sites, hierarchy order)" if isinstance(original, Motion)
                                    else " (markers)"), fontsize=10, loc="left")
    ax_pts.legend(loc="upper right", fontsize=8, frameon=False)
    ax_pts.grid(axis="y", alpha=0.3)

    # over time
    ax_time.fill_between(t, 0, np.nan_to_num(per_frame_mean), color="#fdb863", alpha=0.7, label="mean over points",
                         linewidth=0)
    ax_time.plot(t, per_frame_p99, color="#e66101", linewidth=0.9, label="99th percentile")
    ax_time.plot(t, per_frame_max, color="#b2182b", linewidth=0.9, label="largest")
    ax_time.set_ylabel(f"error ({unit})")
    ax_time.set_ylim(bottom=0)
    ax_time.set_title("over time", fontsize=10, loc="left")
    ax_time.legend(loc="upper right", fontsize=8, frameon=False, ncol=3)
    ax_time.grid(alpha=0.3)
    ax_time.tick_params(labelbottom=False)

    # heat map: points x time
    vmax = float(np.nanmax(e)) if ok.any() and np.nanmax(e) > 0 else 1.0
    dt = 1.0 / original.frame_rate
    im = ax_heat.imshow(np.where(ok, e0, np.nan).T, aspect="auto", interpolation="nearest", cmap="magma_r",
                        vmin=0.0, vmax=vmax, extent=(-0.5 * dt, t[-1] + 0.5 * dt, points - 0.5, -0.5))
    ax_heat.set_xlabel("time (s)")
    ax_heat.set_ylabel("point")
    ax_heat.set_title("every point over time", fontsize=10, loc="left")
    fig.colorbar(im, cax=cax, label=f"error ({unit})")

    buf = io.BytesIO()
    metadata: dict[str, Any] = {"Software": None} if fmt == ".png" else {"Creator": None}
    if fmt == ".pdf":
        metadata["CreationDate"] = None
    elif fmt == ".svg":
        metadata = {"Date": None, "Creator": None}
    fig.savefig(buf, format=fmt[1:], metadata=metadata)
    data = buf.getvalue()
    atomic_write(path, lambda tmp: tmp.write_bytes(data), force=force)
    return path
