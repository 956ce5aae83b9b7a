"""Stream against file on every shared clip (issue 13): the size of a stream of a clip's first frames against
``mocapz.compress`` of the same frames, and what the stream's decoded frames show.

For every BVH, ASF/AMC, C3D and TRC file under ``../shared/data`` (``mocapz.bench.corpus.discover``; a C3D
file's analogs and parameters left out: a stream carries positions only), its first ``--frames`` frames are
coded per codec at max error 1 cm (the default target: feet held)

* offline: ``mocapz.compress`` (one block, one lifting pyramid, one model);
* as a stream: ``mocapz.StreamEncoder`` at its defaults (blocks of about 1 s, a key block every 10 s), fed in
  chunks of random sizes (1 to 59 frames, seed 1);

and the stream is decoded with ``mocapz.decompress``: the column *target* says whether the max error holds on
every point of every frame, *feet* the stream's ``foot_skate`` (METRICS.md, cm/s, on the whole decoded stream;
blank where no foot is planted or the unit is unknown; the summary names the files over issue 11's 0.5 cm/s),
*jitter* its added acceleration energy (``jitter_pct``, %, on the whole decoded stream; the summary names the files
over the correction's allowance, :data:`mocapz.codecs.correction.energy.JITTER`).

Usage::

    .venv/bin/python scripts/stream_sizes.py                       # quant, pga, pga on its model; 1,200 frames
    .venv/bin/python scripts/stream_sizes.py --codecs quant --frames 600 --out /tmp/s.md

Writes docs/benchmarks/stream_sizes.md (or --out) and prints it.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import mocapz
from mocapz.bench.corpus import default_data_dir, discover
from mocapz.codecs.correction.energy import JITTER
from mocapz.errors import MocapzError

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "benchmarks" / "stream_sizes.md"
TARGET = "1cm"
FEET_CM_S = 0.5  # issue 11's criterion for held feet (added foot skate, frame to frame)


def _spec(spec: str) -> tuple[str, dict[str, int | float | str]]:
    """``codec`` or ``codec:name=value,...`` (e.g. ``pga:geodesics=16``): the codec and its given options."""
    codec, _, rest = spec.partition(":")
    options: dict[str, int | float | str] = {}
    for item in filter(None, rest.split(";")):
        name, _, value = item.partition("=")
        options[name] = int(value) if value.isdigit() else value
    return codec, options


def _stream(m: mocapz.AnyMotion, spec: str) -> bytes:
    codec, options = _spec(spec)
    enc = mocapz.StreamEncoder(m, codec=codec, max_error=TARGET, **options)
    rng = np.random.default_rng(1)
    out, i = bytearray(), 0
    while i < m.n_frames:
        k = int(rng.integers(1, 60))
        out += enc.write(m.values[i:i + k])
        i += k
    return bytes(out + enc.close())


def measure(path: Path, spec: str, frames: int) -> dict | None:
    """One file and codec: sizes and the stream's figures, or None where the codec does not take the file."""
    m = mocapz.load(path)
    m.metadata.pop("c3d", None)
    m = m.slice(0, min(m.n_frames, frames))
    if not m.n_frames:
        return None
    codec, options = _spec(spec)
    try:
        offline = len(mocapz.compress(m, codec=codec, max_error=TARGET, **options))
    except MocapzError:
        return None
    data = _stream(m, spec)
    rep = mocapz.evaluate(m, mocapz.decompress(data))
    limit = 1.0 / m.unit_cm if m.unit_cm else None
    met = rep.max_err <= limit * (1 + 1e-9) if limit is not None else None
    feet = rep.foot_skate * m.unit_cm if m.unit_cm and rep.foot_skate is not None else None
    return {"frames": m.n_frames, "fps": m.frame_rate, "offline": offline, "stream": len(data), "met": met,
            "feet": feet, "jitter": rep.jitter_pct}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--codecs", default="quant,pga,pga:geodesics=16",
                    help="codecs, each optionally with options given to the file and the stream alike "
                         "(codec:name=value;name=value)")
    ap.add_argument("--frames", type=int, default=1200)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    root = default_data_dir()
    clips = discover([root])
    t0 = time.time()
    lines = ["# Streams against files on every shared clip", "",
             f"Written by `scripts/stream_sizes.py --codecs {args.codecs} --frames {args.frames}` on "
             f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. See the script's docstring: each file's first "
             f"{args.frames} frames at max error 1 cm (feet held), streamed in blocks of about 1 s (a key block "
             "every 10 s), against the offline file of the same frames. Issue 13 asks for streams within 10 % "
             "of the offline file. A pga stream's block takes the correction alone (continuing the block "
             "before) where that codes it smaller than the pose model and its correction, as a pga file may not "
             "(it always codes on its model); `pga:geodesics=16` gives a pga setting, which keeps the file and every "
             "block on the model: the cost of streaming on the model.", ""]
    summary = []
    for codec in args.codecs.split(","):
        rows, rel, loose, shaky = [], [], [], []
        for clip in clips:
            try:
                r = measure(clip.path, codec, args.frames)
            except MocapzError as exc:  # a file the readers refuse (its own problem, named)
                print(f"{clip.clip_id}: {exc}", file=sys.stderr)
                continue
            if r is None:
                continue
            d = r["stream"] / r["offline"] - 1
            rel.append(d)
            if r["feet"] is not None and r["feet"] > FEET_CM_S:
                loose.append(clip.clip_id)
            if r["jitter"] is not None and r["jitter"] > 100 * JITTER:
                shaky.append(clip.clip_id)
            feet = "" if r["feet"] is None else f"{r['feet']:.3f}"
            jitter = "" if r["jitter"] is None else f"{r['jitter']:.2f}"
            met = "n/a" if r["met"] is None else ("met" if r["met"] else "MISSED")
            rows.append(f"| {clip.clip_id} | {r['frames']:,} | {r['fps']:g} | {r['offline']:,} | {r['stream']:,} | "
                        f"{100 * d:+.1f} % | {met} | {feet} | {jitter} |")
            print(rows[-1], flush=True)
        within = sum(d <= 0.10 for d in rel)
        over, jittery = ", ".join(loose) or "none", ", ".join(shaky) or "none"
        summary.append(f"| {codec} | {len(rel)} | {100 * statistics.median(rel):+.1f} % | {within} of {len(rel)} | "
                       f"{100 * max(rel):+.1f} % | {over} | {jittery} |" if rel else f"| {codec} | 0 | | | | | |")
        lines += [f"## {codec}", "", "| clip | frames | fps | offline B | stream B | stream vs offline | target "
                  "| stream's foot skate cm/s | stream's jitter % |", "|---|---|---|---|---|---|---|---|---|", *rows,
                  ""]
    head = ["## Summary", "", "| codec | files | median stream vs offline | within 10 % | largest | stream's feet over "
            f"{FEET_CM_S} cm/s | stream's jitter over {100 * JITTER:g} % |", "|---|---|---|---|---|---|---|", *summary,
            "", f"Run time {time.time() - t0:.0f} s.", ""]
    text = "\n".join(lines[:4] + head + lines[4:])
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
