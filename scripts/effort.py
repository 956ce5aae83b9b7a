"""The ``effort`` option: bytes and encode time of each effort on the 14 shared CMU BVH clips (or every readable
shared file, ``--clips all``: BVH, ASF/AMC, C3D, TRC, their first 3,000 frames; pga skips marker files) at one target.

Per codec, one process (numba loaded and every kernel compiled first, on 900 frames of 06_13), every clip
encoded at each effort in turn, alternating (so a busy machine slows every effort alike): the file's bytes, the
encode seconds (the library call on a loaded clip), the max error over every joint and end site of every
frame (checked against the target) and the feet's added skate (METRICS.md). Writes
``docs/benchmarks/effort.md``::

    python scripts/effort.py [--codecs quant,pga,patterns] [--efforts fast,medium,best] [--target 1cm]
                             [--clips 09_06,02_05 | all] [--out FILE]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import mocapz
from mocapz.codecs import get_codec
from mocapz.codecs.target import EFFORTS
from mocapz.model.units import parse_length

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
DATA = SHARED / "cmu" / "bvh"
FIRST = 3000  # frames of a longer file measured with --clips all


def measure(codec: str, efforts: list[str], target: str, clips: list[Path]) -> list[dict]:
    """One row per clip: ``{clip, frames, <effort>: (bytes, seconds, max error cm, skate cm/s)}``."""
    warm = mocapz.load(DATA / "06_13.bvh").slice(0, 900)
    for e in efforts:
        mocapz.compress(warm, codec, max_error=target, effort=e)
    rows = []
    limit_cm = parse_length(target).in_file_units(1.0)  # centimetres
    for path in clips:
        try:
            m = mocapz.load(path)
        except mocapz.MocapzError:  # a shared file that is broken on purpose
            continue
        if m.kind not in get_codec(codec).kinds or m.unit_cm is None:  # pga: skeletons; a target in cm: a known unit
            continue
        m = m.slice(0, FIRST) if m.n_frames > FIRST else m
        name = path.stem if path.parent == DATA else str(path.relative_to(SHARED))
        row: dict = {"clip": name, "frames": m.n_frames}
        for e in efforts:
            t = time.perf_counter()
            data = mocapz.compress(m, codec, max_error=target, effort=e)
            dt = time.perf_counter() - t
            rep = mocapz.evaluate(m, mocapz.decompress(data))
            if rep.max_err_cm is None or rep.max_err_cm > limit_cm * (1 + 1e-9):
                raise SystemExit(f"{path.stem} {codec} effort {e}: max error {rep.max_err_cm} cm over {target}")
            row[e] = (len(data), dt, rep.max_err_cm, rep.foot_skate)
        rows.append(row)
        print(codec, row, flush=True)
    return rows


def report(results: dict[str, list[dict]], efforts: list[str], target: str, args: str) -> str:
    ref = "medium" if "medium" in efforts else efforts[0]
    head = ("| codec | " + " | ".join(f"{e}: bytes | {e}: frames/s" for e in efforts)
            + f" | bytes against {ref} | speed against {ref} |")
    where = "every readable shared file" if "--clips all" in args else "the shared CMU BVH clips"
    lines = [
        f"# Effort: bytes and encode speed of each `effort` on {where}",
        "",
        f"Written by `python scripts/effort.py {args}` ({time.strftime('%Y-%m-%d')}, a shared 2-core machine, "
        f"load average {os.getloadavg()[0]:.2f} at the end). Target: max error {target} with planted feet held; "
        "every file was decoded and checked against it. Encode time is the library call on a loaded clip, "
        "numba loaded; the efforts alternate clip by clip in one process, so a busy machine slows them alike: "
        "compare the multiples.",
        "",
        head,
        "|" + "---|" * (1 + 2 * len(efforts) + 2),
    ]
    for codec, rows in results.items():
        frames = sum(r["frames"] for r in rows)
        tot = {e: (sum(r[e][0] for r in rows), sum(r[e][1] for r in rows)) for e in efforts}
        cells = " | ".join(f"{tot[e][0]:,} | {frames / tot[e][1]:,.0f}" for e in efforts)
        vs = ", ".join(f"{e} {100 * (tot[e][0] / tot[ref][0] - 1):+.1f} %" for e in efforts if e != ref)
        sp = ", ".join(f"{e} x{tot[ref][1] / tot[e][1]:.2f}" for e in efforts if e != ref)
        lines.append(f"| {codec} | {cells} | {vs} | {sp} |")
    lines += ["", "Per clip (bytes, seconds, max error cm, added foot skate cm/s):", ""]
    lines += ["| codec | clip | frames | " + " | ".join(efforts) + " |", "|" + "---|" * (3 + len(efforts))]
    for codec, rows in results.items():
        for r in rows:
            cells = " | ".join(f"{r[e][0]:,} B, {r[e][1]:.2f} s, {r[e][2]:.3f}, "
                               f"{'-' if r[e][3] is None else f'{r[e][3]:.2f}'}" for e in efforts)
            lines.append(f"| {codec} | {r['clip']} | {r['frames']:,} | {cells} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--codecs", default="quant,pga,patterns")
    ap.add_argument("--efforts", default="fast,medium,best")
    ap.add_argument("--target", default="1cm")
    ap.add_argument("--clips", default="", help="clip names (default: every CMU BVH clip; all: every shared file)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks" / "effort.md"))
    a = ap.parse_args()
    efforts = a.efforts.split(",")
    if any(e not in EFFORTS for e in efforts):
        raise SystemExit(f"--efforts: each one of {', '.join(EFFORTS)}")
    if a.clips == "all":
        clips = sorted(p for p in SHARED.rglob("*") if p.suffix.lower() in (".bvh", ".amc", ".c3d", ".trc"))
    else:
        clips = [DATA / f"{c}.bvh" for c in a.clips.split(",")] if a.clips else sorted(DATA.glob("*.bvh"))
    results = {c: measure(c, efforts, a.target, clips) for c in a.codecs.split(",")}
    argv = f"--codecs {a.codecs} --efforts {a.efforts} --target {a.target}" + (f" --clips {a.clips}" if a.clips else "")
    Path(a.out).write_text(report(results, efforts, a.target, argv))
    print("wrote", a.out)


if __name__ == "__main__":
    main()
