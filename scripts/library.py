"""Library growth: the 14 shared CMU BVH clips in one ``.mczdb`` against the sum of their single files.

For each codec (pga, quant, patterns) at max error 1 cm: the single ``.mcz`` of every clip, then libraries
of the first n clips of several random shuffles (n = 1, 2, 4, 7, 14): their ratio to the raw float32 size,
the same for the single files of those clips, and the gain (sum of singles / library). Every clip decoded
from the 14-clip library is checked against the target (max error over every joint and end site of every
frame). Writes ``docs/benchmarks/library.md``::

    python scripts/library.py [--codecs pga,quant,patterns] [--shuffles 3] [--jobs 2] [--out FILE]
                              [--results sizes.json [--render]]

``--results`` keeps the measured sizes; ``--render`` writes the report from them without measuring again.
"""

from __future__ import annotations

import argparse
import json
import random
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import mocapz
from mocapz.codecs.pga.library import MODEL_MATRICES
from mocapz.format.container import Container
from mocapz.format.entropy import read_uvarint
from mocapz.format.library import Library
from mocapz.libraries import compress_library, read_clip

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "cmu" / "bvh"
POINTS = (1, 2, 4, 7, 14)
TARGET = "1cm"


def _clips() -> dict[str, Any]:
    return {p.stem: mocapz.load(p) for p in sorted(DATA.glob("*.bvh"))}


def _single(job: tuple[str, str]) -> tuple[str, str, int, int]:
    """A clip's single file: its size and the bytes of it a library could share (layout header, container
    framing, and pga's model matrices)."""
    codec, name = job
    data = mocapz.compress(mocapz.load(DATA / f"{name}.bvh"), codec=codec, max_error=TARGET)
    box = Container.from_bytes(data)
    sharable = len(data) - sum(len(v) for v in box.sections.values())  # layout and framing
    if codec == "pga" and "data" in box.sections and "own" not in box.sections:
        pos = 0
        for _ in range(MODEL_MATRICES):
            n, pos = read_uvarint(box.sections["data"], pos)
            pos += n
        sharable += pos
    return codec, name, len(data), sharable


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


ANALYSIS = [
    "## Why the gain stays small, and what would close the gap to 1.3x", "",
    "A library stores once what every single file repeats: the skeleton (376 bytes in a CMU layout header), the "
    "container's framing and, for pga, the pose model (mean and basis, about 700 bytes). On 09_06 (142 frames) "
    "that is 60 % of the file; on the 14 clips ({frames} frames) it is the *sharable* column above, {shares} of "
    "the single files, so no sharing of these parts can give more than the *bound* column. The rest is per frame: "
    "at 1 cm the correction layer's residual streams (`c.res`, `c.levels`) are 70-90 % of every file and pga's "
    "trajectories and coordinates most of the rest, and they are the clip's own motion. The CMU clips are also "
    "on 7 skeletons (one per subject: same hierarchy, other offsets), so a skeleton is stored 7 times, not once. "
    "A pose model fitted on all the clips explains each clip less well than its own model (the correction then "
    "spends more), so pga keeps a clip's own model where that is smaller (flag section `own`).", "",
    "What would close the gap is a model of the motion shared by the clips, coded once, that makes the per-frame "
    "streams of every clip smaller. Predicting each clip from the other clips of its subject, measured with the "
    "correction layer itself (`scripts/library_prediction.py`, docs/benchmarks/library_prediction.md: windows and"
    " time warps of a partner clip as the base, smoothed, its side information counted): the library is at best "
    "1.080x smaller than the single quant files where a decoder can follow the order (1.103x if every clip may "
    "take its best partner), and even a base copying each clip's own motion smoothed at 12 frames (0.1 s) gives "
    "1.172x; 1.3x would take bases as close to each clip as its own motion to about 30 ms, which another take of "
    "the subject is on none of the 11 clips that have one. Entropy models of the correction's integers trained on"
    " the library and stored once would save at most their side information (about 1-2 % on long clips). Smaller,"
    " certain gains: skeletons of the same hierarchy stored as offsets against a first one (about 200 bytes per "
    "further subject), and the clips' decimals shared with their skeleton (about 50 bytes per clip).", ""]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--codecs", default="pga,quant,patterns")
    ap.add_argument("--shuffles", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "benchmarks" / "library.md")
    ap.add_argument("--results", type=Path, default=None,
                    help="JSON file of the measured sizes: written after measuring; with --render, read instead")
    ap.add_argument("--render", action="store_true", help="write the report from --results without measuring")
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
    sharable: dict[tuple[str, str], int] = {}
    libs: dict[tuple[str, tuple[str, ...]], tuple[int, float, dict[str, Any]]] = {}
    jobs = sorted({(c, tuple(o[:n])) for c in codecs for o in orders for n in POINTS}, key=lambda j: -len(j[1]))
    if args.render:
        saved = json.loads(args.results.read_text())
        singles = {(c, n): v[0] for c, n, *v in saved["singles"]}
        sharable = {(c, n): v[1] for c, n, *v in saved["singles"]}
        libs = {(c, tuple(sub)): (size, t, extra) for c, sub, size, t, extra in saved["libraries"]}
    else:
        with ProcessPoolExecutor(args.jobs) as pool:
            for codec, name, size, share in pool.map(_single, [(c, n) for c in codecs for n in names]):
                singles[codec, name] = size
                sharable[codec, name] = share
                print(codec, name, size, share, flush=True)
            for codec, sub, size, elapsed, extra in pool.map(_library, jobs):
                libs[codec, sub] = (size, elapsed, extra)
                print(codec, len(sub), size, f"{elapsed:.1f} s", extra, flush=True)
        if args.results is not None:
            args.results.write_text(json.dumps({
                "singles": [[c, n, singles[c, n], sharable[c, n]] for c, n in singles],
                "libraries": [[c, list(sub), *v] for (c, sub), v in libs.items()]}))
    lines = ["# Libraries (`.mczdb`) against single files", "",
             f"The 14 shared CMU BVH clips (`../shared/data/cmu/bvh/*.bvh`, {sum(raw.values())} raw float32 bytes) "
             f"at max error {TARGET}, written by `python scripts/library.py --codecs {args.codecs} --shuffles "
             f"{args.shuffles}`. *Singles*: the sum of the clips' own `.mcz` files (`mocapz compress --codec C "
             f"--max-error {TARGET}`); *library*: `mocapz compress-db CLIPS -o LIB.mczdb --codec C --max-error "
             f"{TARGET}`; *gain* = singles / library. Every clip decoded from the 14-clip library meets the target "
             "on every joint and end site of every frame (its max error is in the last column).", "",
             "*Sharable*: the bytes of the single files a library could store once at best (every layout header "
             "with its skeleton, the container framing, and for pga every clip's pose model); *bound*: the gain "
             "if all of them were shared for free (singles / (singles - sharable)).", "",
             "| codec | singles (bytes) | library (bytes) | gain | bound | sharable (bytes) | ratio singles | "
             "ratio library | shared model bytes | skeletons stored (bytes) | library max error (cm) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    total_raw = sum(raw.values())
    for c in codecs:
        single = sum(singles[c, n] for n in names)
        size, _, extra = libs[c, tuple(orders[0])]
        share = sum(sharable[c, n] for n in names)
        lines.append(f"| {c} | {single} | {size} | {single / size:.3f} | {single / (single - share):.3f} | {share} | "
                     f"{total_raw / single:.2f} | "
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
    shares = {c: sum(sharable[c, n] for n in names) / sum(singles[c, n] for n in names) for c in codecs}
    lines += [t.format(frames=f"{sum(m.n_frames for m in clips.values()):,}",
                       shares=" and ".join(f"{100 * v:.1f} % ({c})" for c, v in shares.items())) for t in ANALYSIS]
    args.out.write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
