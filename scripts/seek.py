"""Random access in the lossy codecs' files: what the seekable layout costs and what a 20-frame seek decodes.

Every shared clip of at least 1,024 frames (the seekable layout's threshold) is compressed with each codec at
its default target twice in one process: with the seekable streams (``c.head`` format 3) and with the single
streams shorter clips keep (format 2, ``window.SEEK_MIN`` raised for the run). Per file: both sizes, the full
decode's time, the 20-frame seek's time (the median over 5 starts spread over the clip of each start's best of
``--repeat`` calls, as ``scripts/speed.py`` does) and the share of the range-coded values the seek decodes
(counted, so machine-independent). Every seek is checked equal, to the bit, to the full decode's frames.
pga's single streams also go without its ``turns`` section (written with the seekable layout only).
Writes ``docs/benchmarks/seek.md``::

    python scripts/seek.py [--codecs quant,patterns,pga] [--clips 06_13,01_01.amc] [--repeat 7] [--out FILE]
"""

# ruff: noqa: I001  (mocapz before numpy: it pins the BLAS kernels, see mocapz._blas)
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import mocapz
import numpy as np
from mocapz.codecs import get_codec
from mocapz.codecs.correction import window
from mocapz.format import entropy
from mocapz.format.container import Container

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
CLIPS = ["cmu/bvh/*.bvh", "cmu/asfamc/01_01.amc", "cmu/asfamc/lambada.amc", "cmu/c3d/01_01.c3d",
         "other/bvh/bandai_namco/dataset-1_dance-short_normal_001.bvh", "other/asfamc/amcparser/walking.amc"]
SEEK_FRAMES, SEEK_STARTS = 20, 5


def clips(names: list[str] | None) -> list[Path]:
    """The shared files of :data:`CLIPS` (or those whose name starts with one of ``names``)."""
    paths = [p for pattern in CLIPS for p in sorted(DATA.glob(pattern))]
    return [p for p in paths if names is None or any(p.name.startswith(n) for n in names)]


def counted_values(call) -> int:  # noqa: ANN001
    """The range-coded values ``call()`` decodes."""
    real, total = entropy._decode_values, [0]

    def counting(dec, scale, rows, cols, row0=0):  # noqa: ANN001, ANN202
        total[0] += rows * cols
        return real(dec, scale, rows, cols, row0)

    entropy._decode_values = counting
    try:
        call()
    finally:
        entropy._decode_values = real
    return total[0]


def best_of(call, repeat: int) -> float:  # noqa: ANN001
    call()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        call()
        times.append(time.perf_counter() - t)
    return min(times)


def measure(path: Path, codec: str, repeat: int) -> dict | None:
    motion = mocapz.load(path)
    n = motion.n_frames
    if n < window.SEEK_MIN or motion.kind not in get_codec(codec).kinds:
        return None
    data = mocapz.compress(motion, codec=codec)
    saved, window.SEEK_MIN = window.SEEK_MIN, 10**12
    try:
        plain = mocapz.compress(motion, codec=codec)
    finally:
        window.SEEK_MIN = saved
    head = Container.from_bytes(data).sections["c.head"]
    full = mocapz.decompress(data)
    starts = [int((n - SEEK_FRAMES) * (k + 0.5) / SEEK_STARTS) for k in range(SEEK_STARTS)]
    for a in starts:
        part = mocapz.decompress(data, frames=slice(a, a + SEEK_FRAMES))
        if not np.array_equal(part.values, full.values[a:a + SEEK_FRAMES], equal_nan=True):
            raise SystemExit(f"{path.name} {codec}: frames {a}..{a + SEEK_FRAMES} differ from the full decode")
    decode_s = best_of(lambda: mocapz.decompress(data), repeat)
    seeks = [best_of(lambda a=a: mocapz.decompress(data, frames=slice(a, a + SEEK_FRAMES)), repeat) for a in starts]
    mid = starts[SEEK_STARTS // 2]
    whole_values = counted_values(lambda: mocapz.decompress(data))
    seek_values = counted_values(lambda: mocapz.decompress(data, frames=slice(mid, mid + SEEK_FRAMES)))
    row = {"clip": path.name, "codec": codec, "frames": n, "base": "zero" if head[1] == 0 else "model",
           "bytes": len(data), "plain": len(plain), "decode_s": decode_s, "seek_s": statistics.median(seeks),
           "values": seek_values / whole_values if whole_values else None}
    print(row, file=sys.stderr, flush=True)
    return row


def report(rows: list[dict], args: str) -> str:
    lines = [
        "# Seek in the lossy codecs' files: the seekable layout's cost and a 20-frame seek",
        "",
        f"Written by `python scripts/seek.py {args}` ({time.strftime('%Y-%m-%d')}, a shared 2-core machine, load "
        f"average {os.getloadavg()[0]:.2f} at the end). Default target (max error 1 cm, planted feet held). "
        "*single streams*: the same clip and target with the layout of clips under 1,024 frames; *seek*: the "
        "median over 5 starts of 20 frames, each start's best of the repeats, against the full decode's best; "
        "*values decoded*: the share of the range-coded values the middle seek decodes (counted). Every seek "
        "equals the full decode's frames to the bit. A file whose correction sits on a model base decodes whole, but "
        "pga's: its streams are decoded whole, their trajectories only where the frames reach, its IK solved on the "
        "frames only (the angles' whole turns stored in its `turns` section).",
        "",
        "| clip | codec | frames | base | bytes | single streams | layout cost | full decode ms | seek ms "
        "| seek / full | values decoded |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        share = "" if r["values"] is None else f"{100 * r['values']:.1f} %"
        lines.append(f"| {r['clip']} | {r['codec']} | {r['frames']:,} | {r['base']} | {r['bytes']:,} | "
                     f"{r['plain']:,} | {100 * (r['bytes'] / r['plain'] - 1):+.2f} % | {1e3 * r['decode_s']:.1f} | "
                     f"{1e3 * r['seek_s']:.2f} | {100 * r['seek_s'] / r['decode_s']:.1f} % | {share} |")
    for codec in sorted({r["codec"] for r in rows}):
        mine = [r for r in rows if r["codec"] == codec]
        total, plain = sum(r["bytes"] for r in mine), sum(r["plain"] for r in mine)
        seekable = [r for r in mine if r["base"] == "zero" or codec == "pga"]
        pct = [100 * r["seek_s"] / r["decode_s"] for r in seekable]
        which = "files" if codec == "pga" else "zero-base files"
        lines += ["", f"- **{codec}**: {len(mine)} files, {total:,} B against {plain:,} B with single streams "
                      f"({100 * (total / plain - 1):+.2f} %)" + (
                          f"; on the {len(seekable)} {which} a seek costs {min(pct):.1f} to {max(pct):.1f} % "
                          f"of a full decode (median {statistics.median(pct):.1f} %)" if seekable else "") + "."]
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--codecs", default="quant,patterns,pga")
    ap.add_argument("--clips", default=None, help="file name prefixes (default: every clip of CLIPS)")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "benchmarks" / "seek.md")
    a = ap.parse_args()
    rows = [r for path in clips(a.clips.split(",") if a.clips else None) for codec in a.codecs.split(",")
            if (r := measure(path, codec, a.repeat)) is not None]
    args = " ".join(sys.argv[1:])
    a.out.write_text(report(rows, args))
    print(f"wrote {a.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
