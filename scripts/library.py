"""Library growth: the 14 shared CMU BVH clips in one ``.mczdb`` against the sum of their single files.

For each codec (pga, quant, patterns) at max error 1 cm: the single ``.mcz`` of every clip, then libraries
of the first n clips of several random shuffles (n = 1, 2, 4, 7, 14): their ratio to the raw float32 size,
the same for the single files of those clips, and the gain (sum of singles / library). Every clip decoded
from the 14-clip library is checked against the target (max error over every joint and end site of every
frame). Writes ``docs/benchmarks/library.md``::

    python scripts/library.py [--codecs pga,quant,patterns] [--shuffles 3] [--jobs 2] [--out FILE]
"""

from __future__ import annotations

import argparse
import random
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import mocapz
from mocapz.format.library import Library
from mocapz.libraries import compress_library, read_clip

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "cmu" / "bvh"
POINTS = (1, 2, 4, 7, 14)
TARGET = "1cm"


def _clips() -> dict[str, Any]:
    return {p.stem: mocapz.load(p) for p in sorted(DATA.glob("*.bvh"))}


def _single(job: tuple[str, str]) -> tuple[str, str, int]:
    codec, name = job
    return codec, name, len(mocapz.compress(mocapz.load(DATA / f"{name}.bvh"), codec=codec, max_error=TARGET))


def _library(job: tuple[str, tuple[str, ...]]) -> tuple[str, tuple[str, ...], int, float, dict[str, Any]]:
    codec, names = job
    motions = [mocapz.load(DATA / f"{n}.bvh") for n in names]
    t0 = time.perf_counter()
    data = compress_library(motions, codec=codec, max_error=TARGET)
    elapsed = time.perf_counter() - t0
    extra: dict[str, Any] = {}
    if len(names) == max(POINTS):  # the whole library: check every clip, sizes
        extra["max_err_cm"] = max(mocapz.evaluate(m, read_clip(data, m.name)).max_err_cm for m in motions)
        lib = Library.from_bytes(data)
        extra["shared"] = sum(len(v) for k, v in lib.sections.items() if k.startswith("g"))
        extra["skeletons"] = sum(len(v) for k, v in lib.sections.items() if k.startswith("s"))
        extra["n_skeletons"] = len(lib.index["skeletons"])
    return codec, names, len(data), elapsed, extra


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--codecs", default="pga,quant,patterns")
    ap.add_argument("--shuffles", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "benchmarks" / "library.md")
    args = ap.parse_args(argv)
    codecs = args.codecs.split(",")
    clips = _clips()
    names = sorted(clips)
    raw = {n: m.raw_bytes for n, m in clips.items()}
    orders = []
    for s in range(args.shuffles):
        order = names[:]
        random.Random(s).shuffle(order)
        orders.append(order)
    singles: dict[tuple[str, str], int] = {}
    libs: dict[tuple[str, tuple[str, ...]], tuple[int, float, dict[str, Any]]] = {}
    jobs = sorted({(c, tuple(o[:n])) for c in codecs for o in orders for n in POINTS}, key=lambda j: -len(j[1]))
    with ProcessPoolExecutor(args.jobs) as pool:
        for codec, name, size in pool.map(_single, [(c, n) for c in codecs for n in names]):
            singles[codec, name] = size
        for codec, sub, size, elapsed, extra in pool.map(_library, jobs):
            libs[codec, sub] = (size, elapsed, extra)
            print(codec, len(sub), size, f"{elapsed:.1f} s", extra, flush=True)
    lines = ["# Libraries (`.mczdb`) against single files", "",
             f"The 14 shared CMU BVH clips (`../shared/data/cmu/bvh/*.bvh`, {sum(raw.values())} raw float32 bytes) "
             f"at max error {TARGET}, written by `python scripts/library.py --codecs {args.codecs} --shuffles "
             f"{args.shuffles}`. *Singles*: the sum of the clips' own `.mcz` files (`mocapz compress --codec C "
             f"--max-error {TARGET}`); *library*: `mocapz compress-db CLIPS -o LIB.mczdb --codec C --max-error "
             f"{TARGET}`; *gain* = singles / library. Every clip decoded from the 14-clip library meets the target "
             "on every joint and end site of every frame (its max error is in the last column).", "",
             "| codec | singles (bytes) | library (bytes) | gain | ratio singles | ratio library | shared model "
             "bytes | skeletons stored (bytes) | library max error (cm) |", "|---|---|---|---|---|---|---|---|---|"]
    total_raw = sum(raw.values())
    for c in codecs:
        single = sum(singles[c, n] for n in names)
        size, _, extra = libs[c, tuple(orders[0])]
        lines.append(f"| {c} | {single} | {size} | {single / size:.3f} | {total_raw / single:.2f} | "
                     f"{total_raw / size:.2f} | {extra.get('shared', 0)} | {extra.get('n_skeletons')} "
                     f"({extra.get('skeletons')}) | {extra.get('max_err_cm', float('nan')):.3f} |")
    lines += ["", "## Ratio against the number of clips", "",
              "Per shuffle (seeds 0.."f"{args.shuffles - 1}" "), the library of the first n clips of the shuffled "
              "list: its ratio to raw float32, the ratio of those clips' single files, and the gain.", ""]
    for c in codecs:
        lines += [f"### {c}", "", "| n | " + " | ".join(f"shuffle {s}: library / singles (gain)"
                                                       for s in range(args.shuffles)) + " |",
                  "|---|" + "---|" * args.shuffles]
        for n in POINTS:
            cells = []
            for o in orders:
                sub = tuple(o[:n])
                r = sum(raw[x] for x in sub)
                single = sum(singles[c, x] for x in sub)
                size = libs[c, sub][0]
                cells.append(f"{r / size:.2f} / {r / single:.2f} ({single / size:.3f})")
            lines.append(f"| {n} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["Shuffle orders: " + "; ".join(", ".join(o) for o in orders), ""]
    args.out.write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
