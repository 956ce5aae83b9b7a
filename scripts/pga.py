"""Reproduce the PGA paper's Table 2 (Tournier et al. 2008) on the shared CMU clips.

For each clip (the paper's 09_06 and stand-ins for the clips we do not have), whole and without the
cgspeed T-pose first frame, the PGA codec is run with rate control at the paper's distortion; printed:
geodesics, levels of detail, ratio, distortion_pct, max_err (cm), decode and encode ms/frame, the paper's
values beside them, and in the same run the ratio at equal (or lower) distortion of the lossless codec,
subsampling with spline interpolation, and global PCA (all measured through the container, METRICS.md).

Usage: python scripts/pga.py [--quick] [--out docs/benchmarks/pga.md]
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

import mocapz
from mocapz.api import read_container
from mocapz.codecs.pga.params import PGASettings

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu" / "bvh"

# clip, role, paper (clip, k, LOD root, LOD effectors, ratio, d %, decode ms/frame)
CLIPS = [
    ("09_06", "run (the paper's clip)", ("09_06", 6, "4/9", "4/9", 18, 0.36, 7.88)),
    ("03_04", "long walk (stand-in for 17_08 slow walk)", ("17_08", 12, "8/14", "8/14", 182, 0.049, 16.2)),
    ("06_13", "long mixed (stand-in for 15_04 dance/boxing)", ("15_04", 17, "12/16", "12/16", 69, 1.55, 30.6)),
    ("05_18", "dance (stand-in for 85_12 breakdance)", ("85_12", 15, "9/14", "9/14", 97, 0.56, 20.42)),
    ("02_05", "punch/strike (stand-in for 17_10 boxing)", ("17_10", 12, "8/13", "9/13", 61, 0.49, 15.97)),
]


def timed(fn, *args, **kw):  # type: ignore[no-untyped-def]
    t = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t


def best_ratio_at(motion: mocapz.Motion, codec: str, option: str, values: list[int], target: float
                  ) -> tuple[float, int | None, float]:
    """Largest ratio of a baseline codec over a parameter sweep with distortion <= target."""
    best = (0.0, None, float("nan"))
    for v in values:
        try:
            data = mocapz.compress(motion, codec=codec, **{option: v})
        except mocapz.MocapzError:
            continue
        d = mocapz.evaluate(motion, mocapz.decompress(data)).distortion_pct
        r = motion.raw_bytes / len(data)
        if d <= target and r > best[0]:
            best = (r, v, d)
    return best


def run_clip(motion: mocapz.Motion, target: float, quick: bool) -> dict[str, object]:
    data, t_enc = timed(mocapz.compress, motion, codec="pga", max_distortion=target)
    back, t_dec = timed(mocapz.decompress, data)
    rep = mocapz.evaluate(motion, back)
    box, _ = read_container(data)
    s = PGASettings.from_bytes(box.sections["params"])
    levels = int(np.ceil(np.log2(max(motion.n_frames, 2))))
    lossless = mocapz.compress(motion, codec="lossless")
    dim = 3 * len([j for j in range(1, motion.skeleton.n_joints) if motion.skeleton.rotation_order[j]])
    factors = [2, 3, 4, 6, 8, 12] if quick else [2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32]
    comps = list(range(1, min(dim, motion.n_frames), 1 if not quick else 3))
    return {
        "frames": motion.n_frames, "k": s.k, "lod_root": f"{s.lod_root}/{levels}",
        "lod_eff": f"{s.lod_effectors}/{levels}", "lod_coords": f"{s.lod_coords}/{levels}",
        "eff_mode": s.eff_mode, "bytes": len(data), "ratio": motion.raw_bytes / len(data),
        "d": rep.distortion_pct, "max_cm": rep.max_err_cm, "foot_skate": rep.foot_skate,
        "dec_ms": 1000 * t_dec / motion.n_frames, "enc_ms": 1000 * t_enc / motion.n_frames,
        "lossless": motion.raw_bytes / len(lossless),
        "subsample": best_ratio_at(motion, "subsample", "factor", factors, rep.distortion_pct),
        "pca": best_ratio_at(motion, "pca", "components", comps, rep.distortion_pct),
    }


def variance_section(clips: list, out: Path | None) -> list[str]:
    """The paper's Fig. 3: geodesics needed for a share of the inner-joint rotation variance, per clip,
    and the explained-variance curves as a PNG beside the report."""
    from mocapz.codecs.pga.encode import prepare
    from mocapz.codecs.pga.model import k_for_variance

    lines = ["", "## Explained variance (the paper's Fig. 3)", "",
             "Geodesics needed to explain a share of the variance of the inner joint rotations (approximate PGA "
             "in the tangent space at the intrinsic mean; T-pose frame left out).", "",
             "| clip | frames | 90 % | 95 % | 99 % | 99.9 % |", "|---|---|---|---|---|---|"]
    curves = {}
    for clip, _, _ in clips:
        m = mocapz.load(DATA / f"{clip}.bvh").slice(1)
        model = prepare(m, outliers=[]).full_model
        curves[clip] = model.explained()
        ks = [k_for_variance(model, f) for f in (0.9, 0.95, 0.99, 0.999)]
        lines.append(f"| {clip} | {m.n_frames} | " + " | ".join(map(str, ks)) + " |")
    if out is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3.5), dpi=80)
        for clip, c in curves.items():
            ax.plot(np.arange(1, min(len(c), 40) + 1), 100 * c[:40], label=clip)
        ax.set_xlabel("principal geodesics k")
        ax.set_ylabel("variance explained (%)")
        ax.set_ylim(50, 100.5)
        ax.grid(alpha=0.3)
        ax.legend()
        fig.tight_layout()
        png = out.with_name("pga_variance.png")
        fig.savefig(png)
        lines += ["", f"![explained variance]({png.name})"]
    return lines


def fmt_base(b: tuple[float, int | None, float]) -> str:
    r, v, d = b
    return "none meets it" if v is None else f"{r:.1f} (N={v}, d {d:.3f})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="09_06 only")
    ap.add_argument("--out", type=Path, default=None, help="write the markdown table there")
    args = ap.parse_args()
    clips = CLIPS[:1] if args.quick else CLIPS
    lines = [
        "# PGA codec: the paper's Table 2 on the shared CMU clips",
        "",
        f"Command: `python scripts/pga.py{' --quick' if args.quick else ''}` (mocapz {mocapz.__version__}, "
        f"{platform.machine()}, {platform.python_version()}, single process). Rate control at the paper's "
        "distortion for each clip (`--max-distortion d`); every figure measured through the container as "
        "in ../shared/METRICS.md (d over all joints and end sites, max error in cm). *whole* = the file as "
        "it is (cgspeed T-pose first frame coded apart), *-T* = without that frame, as the paper had it.",
        "Baselines are measured in the same run: largest ratio over their parameter sweep whose distortion "
        "is at most the PGA result's (subsample: keep every N-th frame, cubic spline; PCA: N global "
        "components of the channels).",
        "",
        "| clip | variant | frames | k | LOD root | LOD eff. | LOD coords | ratio | d % | max err cm | "
        "dec ms/f | enc ms/f | lossless | subsample | global PCA | paper: clip, k, LOD, ratio, d %, dec ms/f |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for clip, role, paper in clips:
        full = mocapz.load(DATA / f"{clip}.bvh")
        for variant, motion in (("whole", full), ("-T", full.slice(1))):
            t0 = time.perf_counter()
            r = run_clip(motion, paper[5], args.quick)
            pc = f"{paper[0]}, {paper[1]}, {paper[2]}, 1:{paper[4]}, {paper[5]}, {paper[6]}"
            row = (f"| {clip} {role} | {variant} | {r['frames']} | {r['k']} | {r['lod_root']} | {r['lod_eff']} | "
                   f"{r['lod_coords']} | {r['ratio']:.1f} | {r['d']:.3f} | {r['max_cm']:.2f} | "
                   f"{r['dec_ms']:.3f} | {r['enc_ms']:.1f} | {r['lossless']:.2f} | {fmt_base(r['subsample'])} | "
                   f"{fmt_base(r['pca'])} | {pc} |")
            lines.append(row)
            print(row, f"  [{time.perf_counter() - t0:.0f} s]", flush=True)
    lines += ["", "LOD a/b: a finest levels of detail dropped out of b levels. Paper figures are on the paper's "
              "clips (only 09_06 is the same clip here) and its own machine (C++, 2008)."]
    lines += variance_section(clips, args.out)
    text = "\n".join(lines) + "\n"
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    sys.stdout.write("\n" + text)


if __name__ == "__main__":
    main()
