"""Lossless codec over every readable file of ../shared/data: ratio against float32 (METRICS.md), .mcz size, the
source compressed by ``xz -9e`` and by the few-line bzip2 baseline, with the bit-exact round trip checked.

Also each CMU BVH rewritten with mixed precision (trailing zeros cut, ``-0.0000``, one float artefact: the
rewrite of tests/test_lossless_values.py), to show the ratio does not depend on how the numbers are written.

Usage: python scripts/lossless.py [DATA_DIR] [--out docs/benchmarks/lossless.md] [--repeat 3] [--only FILE ...]
(MOCAPZ_NO_NUMBA=1 times the plain numpy path; ``--only`` prints the rows of a few files and writes nothing.)
"""

from __future__ import annotations

import argparse
import bz2
import lzma
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import mocapz
import mocapz.codecs
from mocapz.codecs.lossless.integers import REP_FLOAT32, to_ints
from mocapz.format.container import Container
from mocapz.format.extras import PREFIX
from mocapz.io.asf import find_asf
from mocapz.model.motion import AnyMotion

SUFFIXES = (".bvh", ".amc", ".c3d", ".trc")


def bzip2_baseline(motion: AnyMotion) -> int:
    """The few-line baseline: integers at the file's decimals (float32 bit patterns where there are none: C3D),
    second differences channel by channel, int64 little endian, through bzip2 -9. Gaps count as 0."""
    values = motion.values.reshape(motion.n_frames, -1)
    values = np.where(np.isfinite(values), values, 0.0)
    if motion.decimals is not None:
        dec = np.broadcast_to(np.asarray(motion.decimals, dtype=np.float64), (values.shape[1],))
        x = np.round(values * 10.0**dec).astype(np.int64)
    else:
        x = to_ints(REP_FLOAT32, values)
    d = np.concatenate([x[:2], x[2:] - 2 * x[1:-1] + x[:-2]]) if len(x) > 2 else x
    return len(bz2.compress(np.ascontiguousarray(d.T).astype("<i8").tobytes(), 9))


def source_bytes(path: Path) -> bytes:
    """The source's bytes (an AMC with its ASF skeleton)."""
    if path.suffix.lower() == ".amc":
        return path.read_bytes() + find_asf(path).read_bytes()
    return path.read_bytes()


def mixed_precision(text: str) -> str:
    """A cgspeed BVH's MOTION numbers with trailing zeros cut, zeros after a negative value (and in every other
    frame) written ``-0.0000``, and one float artefact (tests/test_lossless_values.py imports it)."""
    head, motion = text.split("MOTION", 1)
    lines = motion.splitlines()
    rows = [ln.split() for ln in lines[3:] if ln.strip()]
    out: list[list[str]] = []
    prev: list[str] | None = None
    for row in rows:
        cells = []
        for c, tok in enumerate(row):
            if float(tok) == 0 and prev is not None and (float(prev[c]) < 0 or len(out) % 2):
                cells.append("-0.0000")
            elif "." in tok:
                cut = tok.rstrip("0")
                cells.append(cut + "0" if cut.endswith(".") else cut)
            else:
                cells.append(tok)
        out.append(cells)
        prev = row
    r, c = len(out) // 2, 20
    value = float(out[r][c])
    out[r][c] = repr(value - 1e-14 if value else -1e-14)
    return head + "MOTION\n" + "\n".join(lines[1:3]) + "\n" + "\n".join(" ".join(x) for x in out) + "\n"


def point_bytes(data: bytes) -> int:
    """Bytes of the codec's own sections (the marker or channel values): the .mcz without its ``c3d.*`` extras
    (a C3D's analogs, residual words, header and parameters) and without the container's header."""
    sections = Container.from_bytes(data).sections
    return sum(len(v) for k, v in sections.items() if not k.startswith(PREFIX))


def measure(name: str, motion: AnyMotion, source: bytes, repeat: int = 1) -> dict[str, object]:
    enc = dec = float("inf")
    for _ in range(max(repeat, 1)):  # the best of ``repeat`` runs: the machine is shared
        t0 = time.process_time()  # CPU time: other workers' load on the shared machine does not count
        data = mocapz.compress(motion, codec="lossless")
        t1 = time.process_time()
        back = mocapz.decompress(data)
        t2 = time.process_time()
        enc, dec = min(enc, t1 - t0), min(dec, t2 - t1)
    a = np.nan_to_num(motion.values, nan=0.5).view(np.int64)
    b = np.nan_to_num(back.values, nan=0.5).view(np.int64)
    if not np.array_equal(a, b):
        raise SystemExit(f"{name}: the round trip is not bit-exact")
    xz = len(lzma.compress(source, preset=9 | lzma.PRESET_EXTREME))
    return {"name": name, "frames": motion.n_frames, "raw": motion.raw_bytes, "mcz": len(data),
            "point": point_bytes(data), "ratio": motion.raw_bytes / len(data), "xz": xz,
            "bz2": bzip2_baseline(motion), "quantum": getattr(motion, "quantum", None),
            "enc": 1e6 * enc / max(motion.n_frames, 1), "dec": 1e6 * dec / max(motion.n_frames, 1)}


def warm_up(data: Path) -> None:
    """One untimed round trip, so that no file's time includes loading (or compiling) the numba kernels."""
    try:
        from mocapz.codecs.lossless import fast
    except ImportError:  # a mocapz before the numba kernels
        pass
    else:
        fast.kernels(force=True)  # loaded now, not after a million values
    path = data / "cmu" / "bvh" / "09_06.bvh"
    if path.exists():
        mocapz.decompress(mocapz.compress(mocapz.load(path), codec="lossless"))


def rows_for(data: Path, repeat: int = 1) -> list[dict[str, object]]:
    warm_up(data)
    rows = []
    for path in sorted(p for p in data.rglob("*") if p.suffix.lower() in SUFFIXES):
        rel = str(path.relative_to(data))
        try:
            motion = mocapz.load(path)
        except mocapz.FormatError as exc:
            print(f"{rel}: not readable ({exc.problem})", file=sys.stderr)
            continue
        rows.append(measure(rel, motion, source_bytes(path), repeat))
        print(_line(rows[-1]), file=sys.stderr)
    with tempfile.TemporaryDirectory() as tmp:
        for path in sorted((data / "cmu" / "bvh").glob("*.bvh")):
            mixed = Path(tmp) / path.name
            mixed.write_text(mixed_precision(path.read_text()))
            motion = mocapz.load(mixed)
            rows.append(measure(f"cmu/bvh/{path.name} (mixed precision)", motion, mixed.read_bytes(), repeat))
            print(_line(rows[-1]), file=sys.stderr)
    return rows


def _line(r: dict[str, object]) -> str:
    return (f"| {r['name']} | {r['frames']} | {r['ratio']:.3f} | {r['mcz']} | {r['point']} | {r['xz']} "
            f"| {r['mcz'] / r['xz']:.3f} | {r['bz2']} | {r['point'] / r['bz2']:.3f} | {r['enc']:.1f} "
            f"| {r['dec']:.1f} |")


def _kernels_on() -> bool:
    try:
        from mocapz.codecs.lossless import fast
    except ImportError:  # a mocapz before the numba kernels (timing an older checkout with --only)
        return False
    return fast.kernels(force=True) is not None


def report(rows: list[dict[str, object]], repeat: int = 1) -> str:
    cmu = [r for r in rows if str(r["name"]).startswith("cmu/bvh/")]
    worst = min(float(r["ratio"]) for r in cmu) if cmu else float("nan")
    behind = max(float(r["point"]) / float(r["bz2"]) for r in rows) if rows else float("nan")
    kernels = "on" if _kernels_on() else "off (numpy path)"
    raw = sum(int(r["raw"]) for r in cmu if "mixed" not in str(r["name"]))
    mcz = sum(int(r["mcz"]) for r in cmu if "mixed" not in str(r["name"]))
    out = [
        "# Lossless codec: every shared file",
        "",
        "Written by `python scripts/lossless.py` (mocapz lossless codec, version "
        f"{mocapz.codecs.get_codec('lossless').version}; numba kernels {kernels}). Per file: `ratio` = METRICS.md "
        "raw_bytes (float32) / whole .mcz size; `point bytes` = the codec's own sections alone (the .mcz "
        "without a C3D's `c3d.*` sections: analogs, residual words, header and parameters, which the baseline "
        "does not hold; and without the container's header); `xz -9e` = the source file (an AMC with its ASF) "
        "through Python's lzma at preset 9 | EXTREME; `bzip2 baseline` = second differences of the file's "
        "decimal integers (float32 bit patterns for C3D), channel by channel, through bzip2 -9; `point / bzip2` "
        "compares like with like. Every round trip is checked bit for bit (the sign of zero included). Times "
        "are CPU microseconds per frame (process time), codec call only (`mocapz.compress` / "
        f"`mocapz.decompress`, C3D extras included), the best of {repeat} runs, on a shared 2-core machine.",
        "",
        f"CMU BVH clips together: {raw / mcz:.3f} : 1; the lowest CMU BVH ratio, mixed precision included: "
        f"{worst:.3f} : 1. Point sections over the bzip2 baseline: at most {behind:.3f} "
        f"({'every file ahead' if behind < 1 else 'some file behind'}).",
        "",
        "| file | frames | ratio | .mcz bytes | point bytes | xz -9e bytes | .mcz / xz | bzip2 baseline "
        "| point / bzip2 | enc us/f | dec us/f |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        *(_line(r) for r in rows),
        "",
        "Integer C3D files (Eb015pi, si, vi) are measured as the reader gives them: without the POINT:SCALE",
        "quantum on the motion they are coded as float64 values; with it (MarkerMotion.quantum) as integers.",
        "Their bzip2 baseline codes the values rounded to float32, which is not lossless for them.",
        "Where the whole .mcz is larger than the baseline (Eb015*, FP1, PiG_Motion, markers_analogs) the",
        "difference is the C3D extras (mostly the analog channels, `c3d.ana`), which the baseline leaves out.",
        "",
    ]
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", nargs="?", type=Path,
                        default=Path(__file__).resolve().parents[2] / "shared" / "data")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "benchmarks"
                        / "lossless.md")
    parser.add_argument("--repeat", type=int, default=3, help="time each file this many times, keep the best")
    parser.add_argument("--only", nargs="+", metavar="FILE",
                        help="just time these files (paths under DATA_DIR): print their rows, write nothing")
    args = parser.parse_args()
    if args.only:
        warm_up(args.data)
        for rel in args.only:
            path = args.data / rel
            print(_line(measure(rel, mocapz.load(path), source_bytes(path), args.repeat)), flush=True)
        return
    text = report(rows_for(args.data, args.repeat), args.repeat)
    args.out.write_text(text)
    print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
