"""Reproduce the pattern-indexing paper (Gu, Peng & Deng 2008) with the ``patterns`` codec.

Prints and writes (``docs/benchmarks/patterns.md`` + ``patterns_growth.png``):

* a Table I-style table (original size, segments, clusters, compressed size, ARMS in mm, ratio) for
  cmu/c3d/01_01.c3d, the other shared marker files and several BVH / ASF-AMC clips, with rate control;
* the Fig. 9 comparison against global PCA (95 % variance) and subsampling (factor 12), at their measured
  errors;
* the Fig. 8 local distortion control (a shoulder marker's weight 0.1 / 1 / 10);
* the Figs. 10-11 library growth curves (mixed CMU clips; one motion type), with zstd and subsampling;
* encoding time against input size, beside the lossless codec in the same run.

All sizes are METRICS.md ``raw_bytes`` (float32) over the whole compressed file; ARMS excludes gaps.

Usage: python scripts/patterns.py [--quick] [--out docs/benchmarks/patterns.md]
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import zstandard

import mocapz
from mocapz.api import read_container
from mocapz.codecs.patterns.quantise import decode_patterns
from mocapz.codecs.patterns.segments import decode_segments
from mocapz.format.library import Library
from mocapz.libraries import compress_library, read_clip
from mocapz.model.motion import MarkerMotion

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
warnings.filterwarnings("ignore", category=RuntimeWarning)  # nan-means over all-missing markers

PAPER_TABLE = [("short jumping motion", "10.12 MB", 2724, 121, "0.41 MB", 6.35, 25),
               ("long jumping motion", "530.12 MB", 154262, 3816, "12.62 MB", 4.12, 42),
               ("short combined motion", "10.30 MB", 3017, 154, "0.45 MB", 6.48, 23),
               ("long combined motion", "592.42 MB", 169845, 6126, "21.16 MB", 5.32, 28)]
MIXED = ["01_01", "02_01", "02_03", "02_05", "02_07", "03_04", "05_02", "05_18", "06_10", "06_13", "09_01",
         "09_06", "09_12", "12_01"]
LOCOMOTION = ["02_01", "12_01", "09_01", "09_06", "02_03", "09_12", "03_04"]  # walks and runs
GROWTH = {"bits": 3, "tolerance": 0.05}  # fixed parameters of the growth curves (paper: "same as Fig. 9")


def load(rel: str) -> Any:
    """A shared clip; for C3D the marker stream only, as the paper counts (the file's analogs, parameters
    and residuals, kept losslessly in ``.mcz`` files by default, are left out of these tables)."""
    m = mocapz.load(DATA / rel)
    m.metadata.pop("c3d", None)
    return m


def mm(motion: Any, value: float) -> float:
    unit_cm = motion.unit_cm if isinstance(motion, MarkerMotion) else motion.skeleton.unit_cm
    return value * unit_cm * 10.0


def timed(fn: Any, *args: Any, **kw: Any) -> tuple[Any, float]:
    t = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t


def counts(data: bytes) -> tuple[int, int]:
    """Segments and clusters (all nodes) of a ``.mcz`` written by the patterns codec."""
    box, _ = read_container(data)
    segs = clusters = 0
    k = 1
    while f"d{k}" in box.sections:
        patterns, _ = decode_patterns(box.sections[f"d{k}"])
        labels, _ = decode_segments(box.sections[f"s{k}"], len(patterns))
        segs, clusters, k = segs + len(labels), clusters + len(patterns), k + 1
    return segs, clusters


def code(motion: Any, **options: Any) -> dict[str, Any]:
    data, enc = timed(mocapz.compress, motion, codec="patterns", **options)
    dec, dt = timed(mocapz.decompress, data)
    rep = mocapz.evaluate(motion, dec)
    segs, clusters = counts(data)
    return {"bytes": len(data), "ratio": motion.raw_bytes / len(data), "arms_mm": mm(motion, rep.arms),
            "dist": rep.distortion_pct, "segments": segs, "clusters": clusters, "encode_s": enc,
            "decode_ms_frame": 1000 * dt / motion.n_frames, "data": data, "decoded": dec}


def fmt_bytes(n: float) -> str:
    return f"{n / 1e6:.2f} MB" if n >= 1e6 else f"{n / 1e3:.1f} kB"


# ------------------------------------------------------------------ Table I
def table_one(quick: bool) -> list[str]:
    rows: list[tuple[str, str, dict[str, Any]]] = []
    lines = ["## Table I: single clips, rate control on ARMS", "",
             "`--max-arms` targets as given; BVH / AMC ARMS is on joint and end-site positions (METRICS.md) with "
             "the CMU unit 5.644 cm. `paper settings` = the paper's operating parameters without rate control: "
             "8-bit deltas, world-axis offsets (`heading=False`), MaxError threshold 1 % of the ADDH.", "",
             "| clip | data | frames | original (raw) | setting | segments | clusters | compressed | ARMS mm "
             "| ratio | encode s |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    c3d = load("cmu/c3d/01_01.c3d")
    jobs: list[tuple[str, Any, dict[str, Any]]] = [
        ("cmu/c3d/01_01.c3d", c3d, {"max_arms": "6.5mm"}),
        ("cmu/c3d/01_01.c3d", c3d, {"max_arms": "4mm"}),
        ("cmu/c3d/01_01.c3d", c3d, {"bits": 8, "tolerance": 0.01, "heading": False}),
    ]
    if not quick:
        jobs += [("other/markers/pyomeca/markers_analogs.c3d", load("other/markers/pyomeca/markers_analogs.c3d"),
                  {"max_arms": "6.5mm"}),
                 ("other/markers/btkdata/Gait.trc", load("other/markers/btkdata/Gait.trc"), {"max_arms": "6.5mm"})]
    bvh = ["09_06", "02_01", "05_02"] if quick else ["09_06", "02_01", "05_02", "06_13", "01_01"]
    jobs += [(f"cmu/bvh/{c}.bvh", load(f"cmu/bvh/{c}.bvh"), {"max_arms": "6.5mm"}) for c in bvh]
    if not quick:
        jobs.append(("cmu/asfamc/01_01.amc", load("cmu/asfamc/01_01.amc"), {"max_arms": "6.5mm"}))
    for rel, motion, opts in jobs:
        r = code(motion, **opts)
        setting = ", ".join(f"{k}={v}" for k, v in opts.items())
        if "max_arms" not in opts:
            setting = "paper settings: " + setting
        kind = "markers" if isinstance(motion, MarkerMotion) else "skeleton"
        lines.append(f"| {rel} | {kind} | {motion.n_frames} | {fmt_bytes(motion.raw_bytes)} | {setting} | "
                     f"{r['segments']} | {r['clusters']} | {fmt_bytes(r['bytes'])} | {r['arms_mm']:.2f} | "
                     f"{r['ratio']:.1f} | {r['encode_s']:.1f} |")
        rows.append((rel, setting, r))
        print(lines[-1], flush=True)
    lines += ["", "The paper's Table I (CMU marker data, its own sizes; ARMS unit not stated, read as mm):", "",
              "| motion | original | segments | clusters | compressed | ARMS | ratio |",
              "|---|---|---|---|---|---|---|"]
    lines += [f"| {a} | {b} | {c} | {d} | {e} | {f} | {g} |" for a, b, c, d, e, f, g in PAPER_TABLE]
    return lines


# ------------------------------------------------------------------ Fig. 9
def fig_nine() -> list[str]:
    m = load("cmu/c3d/01_01.c3d")
    lines = ["## Fig. 9: against global PCA (95 % variance) and subsampling (factor 12), cmu/c3d/01_01.c3d", "",
             "The baselines store float32 values without entropy coding, as in the paper. The pattern codec is "
             "then run with `--max-arms` set to each baseline's measured ARMS.", "",
             "| method | ARMS mm | distortion % | compressed | ratio | patterns at that ARMS: ratio |",
             "|---|---|---|---|---|---|"]
    for name, codec, opts in (("global PCA, 95 % variance", "pca", {"variance": 0.95}),
                              ("subsampling x12 (cubic spline)", "subsample", {"factor": 12})):
        data = mocapz.compress(m, codec=codec, **opts)
        rep = mocapz.evaluate(m, mocapz.decompress(data))
        ours = code(m, max_arms=f"{rep.arms:.4f}")
        lines.append(f"| {name} | {rep.arms:.2f} | {rep.distortion_pct:.3f} | {fmt_bytes(len(data))} | "
                     f"{m.raw_bytes / len(data):.1f} | {ours['ratio']:.1f} (ARMS {ours['arms_mm']:.2f}) |")
        print(lines[-1], flush=True)
    paper = code(m, max_arms="5.32mm")
    lines.append(f"| patterns at the paper's Fig. 9 ARMS 5.32 | {paper['arms_mm']:.2f} | {paper['dist']:.3f} | "
                 f"{fmt_bytes(paper['bytes'])} | {paper['ratio']:.1f} | |")
    return lines


# ------------------------------------------------------------------ Fig. 8
def fig_eight() -> list[str]:
    m = load("cmu/c3d/01_01.c3d")
    i = m.labels.index("LSHO")
    lines = ["## Fig. 8: local distortion control, weight of the shoulder marker LSHO (cmu/c3d/01_01.c3d)", "",
             "Fixed parameters (bits=3, tolerance=0.05, others default); only the weight of LSHO changes.", "",
             "| LSHO weight | LSHO RMS error mm | LSHO Z max error mm | ARMS all markers mm | compressed |",
             "|---|---|---|---|---|"]
    for w in (0.1, 1.0, 10.0):
        r = code(m, bits=3, tolerance=0.05, weights={"LSHO": w})
        d = r["decoded"].positions[:, i] - m.positions[:, i]
        rms = float(np.sqrt(np.nanmean(np.sum(d**2, axis=1))))
        lines.append(f"| {w:g} | {rms:.2f} | {np.nanmax(np.abs(d[:, 2])):.1f} | {r['arms_mm']:.2f} | "
                     f"{fmt_bytes(r['bytes'])} |")
        print(lines[-1], flush=True)
    return lines


# ------------------------------------------------------------------ Figs. 10-11
def library_point(motions: list[Any], **options: Any) -> dict[str, Any]:
    data, enc = timed(compress_library, motions, **options)
    raw = sum(m.raw_bytes for m in motions)
    lib = Library.from_bytes(data)
    arms = [mm(m, mocapz.evaluate(m, read_clip(data, c["name"])).arms)
            for m, c in zip(motions, lib.index["clips"], strict=True)]
    floats = np.concatenate([(m.positions if isinstance(m, MarkerMotion) else m.channels).astype(np.float32).ravel()
                             for m in motions])
    zst = len(zstandard.ZstdCompressor(level=19).compress(floats.tobytes()))
    return {"clips": len(motions), "frames": sum(m.n_frames for m in motions), "raw": raw, "bytes": len(data),
            "ratio": raw / len(data), "arms_max": max(arms), "arms_mean": float(np.mean(arms)), "encode_s": enc,
            "zstd_ratio": raw / zst, "segments": sum(g["segments"] for g in lib.index["groups"]),
            "clusters": sum(g["clusters"] for g in lib.index["groups"])}


def growth(quick: bool) -> tuple[list[str], dict[str, list[dict[str, Any]]]]:
    mixed_names = MIXED[:5] if quick else MIXED
    clips = {n: load(f"cmu/bvh/{n}.bvh") for n in set(mixed_names + LOCOMOTION)}
    curves: dict[str, list[dict[str, Any]]] = {"mixed CMU clips": [], "one type (walks and runs)": [],
                                               "one clip repeated (paper Fig. 11)": []}
    for n in range(1, len(mixed_names) + 1):
        curves["mixed CMU clips"].append(library_point([clips[c] for c in mixed_names[:n]], **GROWTH))
        print("mixed", curves["mixed CMU clips"][-1], flush=True)
    loco = LOCOMOTION[:4] if quick else LOCOMOTION
    for n in range(1, len(loco) + 1):
        curves["one type (walks and runs)"].append(library_point([clips[c] for c in loco[:n]], **GROWTH))
    walk = clips["02_01"]
    total = curves["mixed CMU clips"][-1]["frames"]
    reps = [1, 2, 4, 8, 16, 32, 64]
    for r in [x for x in reps if (x - 1) * walk.n_frames < total] + [max(1, total // walk.n_frames)]:
        copies = [walk] * r
        curves["one clip repeated (paper Fig. 11)"].append(library_point(copies, **GROWTH))
    lines = ["## Figs. 10-11: library growth (`compress-db`)", "",
             f"Fixed parameters ({', '.join(f'{k}={v}' for k, v in GROWTH.items())}, others default), as the "
             "paper keeps its Fig. 9 parameters; every clip is decoded alone from the library (`--clip`) to "
             "measure its ARMS. Baselines: zstd -19 on the float32 values; subsampling x12 is a constant "
             "ratio of about 12 (float32 key frames).", ""]
    for name, pts in curves.items():
        lines += [f"### {name}", "", "| clips | frames | raw | library | ratio | zstd ratio | segments | clusters "
                  "| ARMS mm mean / max | encode s |", "|---|---|---|---|---|---|---|---|---|---|"]
        for p in pts:
            lines.append(f"| {p['clips']} | {p['frames']} | {fmt_bytes(p['raw'])} | {fmt_bytes(p['bytes'])} | "
                         f"{p['ratio']:.1f} | {p['zstd_ratio']:.2f} | {p['segments']} | {p['clusters']} | "
                         f"{p['arms_mean']:.2f} / {p['arms_max']:.2f} | {p['encode_s']:.1f} |")
        lines.append("")
    return lines, curves


def target_library(quick: bool) -> list[str]:
    names = MIXED[:3] if quick else MIXED
    motions = [load(f"cmu/bvh/{n}.bvh") for n in names]
    one = code(motions[0], max_arms="6.5mm")
    lib = library_point(motions, max_arms="6.5mm")
    return ["### Whole shared CMU BVH set at a target (`compress-db --max-arms 6.5mm`)", "",
            "| data | frames | ratio | ARMS mm (max over clips) |", "|---|---|---|---|",
            f"| {names[0]} alone (`compress --max-arms 6.5mm`) | {motions[0].n_frames} | {one['ratio']:.1f} | "
            f"{one['arms_mm']:.2f} |",
            f"| all {len(names)} clips in one library | {lib['frames']} | {lib['ratio']:.1f} | {lib['arms_max']:.2f} |",
            ""]


def plot(curves: dict[str, list[dict[str, Any]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=90)
    for name, pts in curves.items():
        x = [p["raw"] / 1e6 for p in pts]
        ax.plot(x, [p["ratio"] for p in pts], marker="o", ms=3, label=f"patterns: {name}")
    mixed = curves["mixed CMU clips"]
    ax.plot([p["raw"] / 1e6 for p in mixed], [p["zstd_ratio"] for p in mixed], ls="--", label="zstd -19 (mixed)")
    ax.axhline(12.0, color="grey", ls=":", label="subsampling x12")
    ax.set_xlabel("library size (float32 raw, MB)")
    ax.set_ylabel("compression ratio")
    ax.set_title("Library growth (paper Figs. 10-11), CMU BVH")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


# ------------------------------------------------------------------ encode time
def scaling(quick: bool) -> list[str]:
    c3d = load("cmu/c3d/01_01.c3d")
    lines = ["## Encoding time against input size", "",
             "One process, one BLAS thread, fixed parameters (bits=3, tolerance=0.05, no rate control). The "
             "marker clip is cmu/c3d/01_01.c3d repeated end to end; the library rows are the mixed CMU BVH "
             "libraries above. The lossless codec is timed on the same data in the same run as the reference "
             "(METRICS.md: these machines are noisy).", "",
             "| data | frames | patterns encode s | ms/frame | lossless encode s | patterns / lossless |",
             "|---|---|---|---|---|---|"]
    for reps in ((1, 2, 4) if quick else (1, 2, 4, 8)):
        m = c3d.with_positions(np.concatenate([c3d.positions] * reps))
        _, t = timed(mocapz.compress, m, codec="patterns", bits=3, tolerance=0.05)
        _, tl = timed(mocapz.compress, m, codec="lossless")
        lines.append(f"| 01_01.c3d x{reps} | {m.n_frames} | {t:.2f} | {1000 * t / m.n_frames:.3f} | {tl:.2f} | "
                     f"{t / tl:.1f} |")
        print(lines[-1], flush=True)
    names = MIXED[:4] if quick else MIXED
    motions = [load(f"cmu/bvh/{n}.bvh") for n in names]
    for n in sorted({1, len(names) // 4, len(names) // 2, len(names)} - {0}):
        sub = motions[:n]
        _, t = timed(compress_library, sub, **GROWTH)
        tl = sum(timed(mocapz.compress, m, codec="lossless")[1] for m in sub)
        frames = sum(m.n_frames for m in sub)
        lines.append(f"| CMU BVH library, {n} clips | {frames} | {t:.2f} | {1000 * t / frames:.3f} | {tl:.2f} | "
                     f"{t / tl:.1f} |")
        print(lines[-1], flush=True)
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer clips (a few minutes)")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "benchmarks" / "patterns.md")
    args = ap.parse_args(argv)
    t0 = time.time()
    head = ["# Pattern codec (Gu, Peng & Deng 2008) on the shared data", "",
            f"Generated by `python scripts/patterns.py{' --quick' if args.quick else ''}` "
            f"(mocapz {mocapz.__version__}, Python {platform.python_version()}, {platform.machine()}, "
            f"{time.strftime('%Y-%m-%d')}). Ratios are METRICS.md `raw_bytes / compressed_bytes` (float32 raw "
            "size over the whole file, headers and databases included); ARMS is the paper's eq. 3 "
            "(gaps excluded).", ""]
    body = table_one(args.quick) + [""] + fig_nine() + [""] + fig_eight() + [""]
    grow, curves = growth(args.quick)
    body += grow + target_library(args.quick) + [""] + scaling(args.quick)
    png = args.out.with_name("patterns_growth.png")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    plot(curves, png)
    body += ["", f"![library growth]({png.name})", "", f"Total bench time: {time.time() - t0:.0f} s."]
    args.out.write_text("\n".join(head + body) + "\n", encoding="utf-8")
    print(f"wrote {args.out} and {png}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
