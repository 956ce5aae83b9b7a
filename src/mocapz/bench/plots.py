"""PNG plots of a benchmark (matplotlib, Agg backend): rate-distortion per codec, decode speed per codec.

Images are written small (about 700 x 450 pixels, palette PNG) so they can be committed.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.bench.curves import corpus_ratio, metric_points, ratio_at
from mocapz.bench.published import PUBLISHED
from mocapz.bench.report import by_clip_codec
from mocapz.bench.sweeps import GENERIC

LOSSLESS = ("lossless", *GENERIC)
MIN_ERROR = 1e-3  # errors below this (exact settings) are left off the log axes


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _colors(codecs: list[str]) -> dict[str, Any]:
    """Distinct strong colours for lossy codecs, greys for the lossless ones."""
    plt = _pyplot()
    strong = plt.get_cmap("tab10")
    greys = ["#444444", "#777777", "#999999", "#bbbbbb", "#555555", "#888888"]
    out, i, g = {}, 0, 0
    for c in codecs:
        if c in LOSSLESS:
            out[c] = greys[g % len(greys)]
            g += 1
        else:
            out[c] = strong(i % strong.N)
            i += 1
    return out


def _save(fig: Any, path: Path) -> None:
    """Save as a palette PNG (small files); plain PNG if Pillow is missing."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    _pyplot().close(fig)
    try:
        from PIL import Image

        img = Image.open(io.BytesIO(buf.getvalue())).convert("RGB")
        img.quantize(colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE).save(
            path, format="PNG", optimize=True)
    except ImportError:  # pragma: no cover
        path.write_bytes(buf.getvalue())


def corpus_curve(doc: dict[str, Any], codec: str, metric: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The codec's corpus ratio on a grid of error levels where at least half of the clips it ran on reach
    the level: levels ``(n,)``, ratios ``(n,)`` and ``(n,)`` bool, True where every clip reaches it."""
    groups = by_clip_codec(doc)
    curves = [(c["raw_bytes"], metric_points(groups[(c["clip"], codec)], metric)) for c in doc["clips"]
              if (c["clip"], codec) in groups]
    curves = [(raw, pts) for raw, pts in curves if pts]
    errs = [e for _, pts in curves for e, _ in pts if e > MIN_ERROR]
    if not errs:
        return np.zeros(0), np.zeros(0), np.zeros(0, dtype=bool)
    grid = np.geomspace(min(errs), max(errs), 80)
    xs, ys, full = [], [], []
    for level in grid:
        ratio, used = corpus_ratio([(raw, ratio_at(pts, float(level))) for raw, pts in curves])
        if ratio is not None and 2 * used >= len(curves):
            xs.append(level)
            ys.append(ratio)
            full.append(used == len(curves))
    return np.array(xs), np.array(ys), np.array(full, dtype=bool)


def rd_plot(doc: dict[str, Any], metric: str, xlabel: str, path: Path, published: bool) -> None:
    """Ratio against an error figure, log-log: per-clip settings as dots, the corpus curve as a line,
    lossless codecs as horizontal lines, published operating points in black."""
    plt = _pyplot()
    codecs = list(doc["codecs"])
    colors = _colors(codecs)
    groups = by_clip_codec(doc)
    fig, ax = plt.subplots(figsize=(8.6, 4.8))
    dashes = ["--", ":", "-.", (0, (5, 1)), (0, (1, 1)), (0, (3, 1, 1, 1))]
    n_lossless = 0
    for codec in codecs:
        pts = [p for c in doc["clips"] for p in metric_points(groups.get((c["clip"], codec), []), metric)]
        if not pts:
            continue
        if codec in LOSSLESS:
            ratio, _ = corpus_ratio([(c["raw_bytes"], groups[(c["clip"], codec)][0]["ratio"])
                                     for c in doc["clips"] if (c["clip"], codec) in groups])
            if ratio:
                ax.axhline(ratio, color=colors[codec], lw=1.0, ls=dashes[n_lossless % len(dashes)],
                           label=f"{codec} (lossless)")
                n_lossless += 1
            continue
        e = np.array([p[0] for p in pts])
        r = np.array([p[1] for p in pts])
        keep = e > MIN_ERROR
        ax.scatter(e[keep], r[keep], s=7, color=colors[codec], alpha=0.35, linewidths=0)
        xs, ys, full = corpus_curve(doc, codec, metric)
        ax.plot(xs, np.where(full, np.nan, ys), color=colors[codec], lw=1.2, ls="--")
        ax.plot(xs, np.where(full, ys, np.nan), color=colors[codec], lw=2.0)
        ax.plot([], [], color=colors[codec], lw=2.0, label=codec)
    if published:
        for p in PUBLISHED:
            if p.metric != metric or p.error is None:
                continue
            if p.error[0] == p.error[1] and p.ratio[0] == p.ratio[1]:
                ax.plot(p.error[0], p.ratio[0], marker="*", color="black", ms=9, ls="none")
                ax.annotate(p.clip.split()[0], (p.error[0], p.ratio[0]), textcoords="offset points",
                            xytext=(4, 3), fontsize=7)
            else:
                ax.add_patch(plt.Rectangle((p.error[0], p.ratio[0]), p.error[1] - p.error[0],
                                           p.ratio[1] - p.ratio[0], fill=False, ec="black", lw=1.0))
                ax.annotate("L&M 2006", (p.error[1], p.ratio[1]), textcoords="offset points", xytext=(3, 0),
                            fontsize=7)
        ax.plot([], [], marker="*", color="black", ls="none", label="published (their clips)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("compression ratio (raw float32 / compressed)")
    ax.set_xlim(left=MIN_ERROR)
    ax.set_title(f"Ratio against {xlabel}, {len(doc['clips'])} clips. Line: corpus (dashed where only some clips "
                 "reach the error); dots: one clip at one setting", fontsize=8)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    fig.tight_layout()
    _save(fig, path)


def speed_plot(doc: dict[str, Any], path: Path) -> None:
    """Median encode and decode ms/frame per codec (log scale), labelled with the × lossless factor."""
    plt = _pyplot()
    rows = []
    for codec in doc["codecs"]:
        ok = [r for r in doc["records"] if r["codec"] == codec and r.get("status") == "ok"]
        if not ok:
            continue
        dec = float(np.median([r["decode_ms_per_frame"] for r in ok]))
        enc = float(np.median([r["encode_ms_per_frame"] for r in ok]))
        rel = [r["decode_vs_lossless"] for r in ok if r.get("decode_vs_lossless") is not None]
        rows.append((codec, enc, dec, float(np.median(rel)) if rel else None))
    fig, ax = plt.subplots(figsize=(7.8, 0.9 + 0.38 * max(len(rows), 1)))
    y = np.arange(len(rows))
    ax.barh(y + 0.2, [max(r[2], 1e-6) for r in rows], height=0.4, color="tab:blue", label="decode")
    ax.barh(y - 0.2, [max(r[1], 1e-6) for r in rows], height=0.4, color="tab:gray", alpha=0.6, label="encode")
    for i, (_, _, dec, rel) in enumerate(rows):
        if rel is not None:
            ax.annotate(f"{rel:.2g}× lossless", (max(dec, 1e-6), i + 0.2), textcoords="offset points",
                        xytext=(3, -3), fontsize=7)
    ax.set_yticks(y, [r[0] for r in rows])
    ax.invert_yaxis()
    ax.set_xscale("log")
    ax.set_xlabel("ms per frame (median over clips and settings; one thread)")
    ax.set_title("Decode (and encode) speed per codec", fontsize=9)
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(True, axis="x", alpha=0.3)
    fig.tight_layout()
    _save(fig, path)


def write_plots(doc: dict[str, Any], out_dir: Path) -> dict[str, str]:
    """Write the PNGs into ``out_dir``; returns title -> file name."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = {
        "ratio against distortion": "rd_distortion.png",
        "ratio against max error": "rd_max_error.png",
        "decode speed": "speed.png",
    }
    rd_plot(doc, "distortion_pct", "distortion_pct (%)", out_dir / files["ratio against distortion"], True)
    rd_plot(doc, "max_err_cm", "max_err (cm)", out_dir / files["ratio against max error"], False)
    speed_plot(doc, out_dir / files["decode speed"])
    return files
