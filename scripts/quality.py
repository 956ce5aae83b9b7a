"""Quality benchmark (issue 11): the ratio each lossy codec gives at a bound on every point of every frame.

Per shared clip (the 14 CMU BVH clips of ../shared/data/cmu/bvh and a selection of other skeletal and
marker files) and per lossy codec, three targets, each met by the codec's own rate control and checked here
on the decoded result: max error 1 cm, max error 1 mm, distortion d 0.36 %. Per result: the ratio, d, max
error, ARMS, foot skate frame to frame and over 0.1 s windows, jitter, encode time; ACL 2.1's figures
(quoted from issue 11, not measured here) beside the CMU clips. A target the codec refuses (TargetError) is
a row that says so; a result the codec returns that misses its target is marked "missed".

Usage::

    .venv/bin/python scripts/quality.py                          # every clip, every lossy codec
    .venv/bin/python scripts/quality.py --quick                  # 3 short clips (200 frames), a smoke run
    .venv/bin/python scripts/quality.py --clips 09_06,02_01 --codecs pga,quant --jobs 2 --out /tmp/q.md

Writes docs/benchmarks/quality.md (or --out) and prints the summary tables.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from quality_report import render, summary  # noqa: E402

import mocapz  # noqa: E402  (first: pins the BLAS kernels)
from mocapz.bench.measure import BenchTimeout, measure_codec  # noqa: E402
from mocapz.bench.runner import machine, single_thread  # noqa: E402
from mocapz.codecs import get_codec  # noqa: E402
from mocapz.errors import MocapzError, TargetError  # noqa: E402
from mocapz.io import load  # noqa: E402
from mocapz.model.motion import AnyMotion, Motion  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
OUT = ROOT / "docs" / "benchmarks" / "quality.md"

CMU14 = tuple(f"cmu/bvh/{c}.bvh" for c in ("01_01", "02_01", "02_03", "02_05", "02_07", "03_04", "05_02", "05_18",
                                             "06_10", "06_13", "09_01", "09_06", "09_12", "12_01"))
OTHERS = (
    "cmu/bvh_iclone_ccrig/002_03.bvh",
    "other/bvh/bandai_namco/dataset-1_punch_normal_001.bvh",
    "other/bvh/bandai_namco/dataset-2_walk_elderly_004.bvh",
    "other/bvh/games105/walk_and_turn_left.bvh",
    "other/bvh/bvh-python/test_mocapbank.bvh",
    "other/bvh/pymo/AV_8Walk_Meredith_HVHA_Rep1.bvh",
    "cmu/asfamc/11_01.amc",
    "cmu/asfamc/backflip.amc",
    "other/asfamc/amcparser/walking.amc",
    "cmu/c3d/01_01.c3d",
    "other/markers/pyomeca/markers_analogs.c3d",
    "other/markers/btkdata/c3d_samples/Eb015pr.c3d",
    "other/markers/btkdata/Gait.trc",
)
QUICK_CLIPS = ("cmu/bvh/09_06.bvh", "other/bvh/bandai_namco/dataset-1_walk_normal_001.bvh",
               "other/markers/btkdata/Gait.trc")
QUICK_FRAMES = 200
CODECS = ("pga", "patterns", "quant", "subsample", "pca", "segpca")

#: target name -> (options given to the codec, figure it bounds, bound in that figure's unit)
TARGETS: dict[str, tuple[dict[str, Any], str, float]] = {
    "1cm": ({"max_error": "1cm"}, "max_err_cm", 1.0),
    "1mm": ({"max_error": "1mm"}, "max_err_cm", 0.1),
    "d0.36": ({"max_distortion": 0.36}, "distortion_pct", 0.36),
    "arms6.5mm": ({"max_arms": "6.5mm"}, "arms_cm", 0.65),  # marker clips only (the patterns paper's measure)
}
MARKER_ONLY = ("arms6.5mm",)
DEFAULT_TARGETS = ("1cm", "1mm", "d0.36")
SUFFIXES = (".bvh", ".amc", ".c3d", ".trc")
#: relative slack when checking a met target (float rounding between the codec's check and ours)
SLACK = 1e-6


@dataclass(frozen=True)
class Task:
    """One codec at one target on one clip (``frames``: keep the first frames only; ``None``: all)."""

    index: int
    clip: str
    codec: str
    target: str
    frames: int | None
    timeout: float


def clip_id(rel: str) -> str:
    """Short name of a clip: CMU BVH clips by their take (``09_06``), others by their path."""
    return Path(rel).stem if rel.startswith("cmu/bvh/") else rel


def resolve_clips(spec: str | None, quick: bool) -> list[str]:
    """The clips to run: ``--clips`` names (takes like ``09_06``, paths under ../shared/data, or ``cmu14``,
    ``others``, ``every``: every BVH, AMC, C3D and TRC file under ../shared/data), else the quick set or the
    CMU and other clips."""
    if not spec:
        return list(QUICK_CLIPS if quick else CMU14 + OTHERS)
    out: list[str] = []
    for name in (s.strip() for s in spec.split(",") if s.strip()):
        if name == "cmu14":
            out += CMU14
        elif name == "others":
            out += OTHERS
        elif name == "every":  # every shared motion file, readable or not (a refused file is a row too)
            out += sorted(str(p.relative_to(DATA)) for p in DATA.rglob("*")
                          if p.is_file() and p.suffix.lower() in SUFFIXES)
        elif (DATA / name).is_file():
            out.append(name)
        elif (DATA / "cmu" / "bvh" / f"{name}.bvh").is_file():
            out.append(f"cmu/bvh/{name}.bvh")
        else:
            raise SystemExit(f"--clips: no clip {name!r} (a CMU take like 09_06, a path under {DATA}, "
                             "cmu14 or others)")
    return list(dict.fromkeys(out))


def load_clip(rel: str, frames: int | None) -> AnyMotion:
    """The clip, cut to its first ``frames`` frames when given."""
    motion = load(DATA / rel)
    return motion.slice(0, frames) if frames is not None and motion.n_frames > frames else motion


def describe_clip(rel: str, motion: AnyMotion) -> dict[str, Any]:
    """Clip fields of a record: format, frames, rate, kind, unit, raw bytes."""
    rec = {"clip": clip_id(rel), "path": rel, "frames": motion.n_frames, "frame_rate": motion.frame_rate,
           "raw_bytes": motion.raw_bytes}
    if isinstance(motion, Motion):
        rec.update(kind="skeleton", unit_cm=motion.skeleton.unit_cm, unit_note=motion.skeleton.unit_note)
    else:
        rec.update(kind="markers", unit_cm=motion.unit_cm, unit_note=f"marker file in {motion.units}")
    return rec


def run_task(task: Task) -> dict[str, Any]:
    """Compress, decompress and score one task; never raises for a codec's failure (it becomes the status)."""
    rec: dict[str, Any] = {"codec": task.codec, "target": task.target}
    try:
        motion = load_clip(task.clip, task.frames)
    except MocapzError as exc:
        return {**rec, "clip": clip_id(task.clip), "path": task.clip, "status": "error", "message": str(exc)}
    rec.update(describe_clip(task.clip, motion))
    info = get_codec(task.codec)
    if rec["kind"] not in info.kinds:
        return {**rec, "status": "n/a", "message": f"{task.codec} takes {' and '.join(info.kinds)} data only"}
    options, figure, bound = TARGETS[task.target]
    t0 = time.perf_counter()
    try:
        with single_thread():
            figs = measure_codec(motion, task.codec, options, timeout=task.timeout)
    except TargetError as exc:
        return {**rec, "status": "target failed", "message": str(exc), "seconds": time.perf_counter() - t0}
    except BenchTimeout as exc:
        return {**rec, "status": "timeout", "message": str(exc), "seconds": time.perf_counter() - t0}
    except Exception as exc:  # a codec's bug is a row of the report too, not the end of the run
        return {**rec, "status": "error", "message": f"{type(exc).__name__}: {exc}",
                "seconds": time.perf_counter() - t0}
    rec.update(figs)
    rec["encode_s"] = figs["encode_ms_per_frame"] * max(motion.n_frames, 1) / 1000.0
    value = figs.get(figure)
    if value is None:  # unknown unit: a cm target cannot be checked (the codec would have refused it)
        rec.update(status="error", message=f"{figure} unknown for this clip")
    elif value <= bound * (1 + SLACK):
        rec["status"] = "ok"
    else:
        rec.update(status="missed", message=f"{figure} {value:.4g} > {bound:g} although the codec accepted it")
    return rec


def run_tasks(tasks: list[Task], jobs: int, progress: bool = True) -> list[dict[str, Any]]:
    """Every task's record, in task order whatever the number of processes."""
    records: list[dict[str, Any] | None] = [None] * len(tasks)

    def done(i: int, rec: dict[str, Any]) -> None:
        records[i] = rec
        if progress:
            n = sum(r is not None for r in records)
            print(f"[{n}/{len(tasks)}] {rec['clip']} {rec['codec']} {rec['target']}: {rec['status']}"
                  + (f" {rec['ratio']:.3g}:1" if rec.get("ratio") else ""), file=sys.stderr, flush=True)

    if jobs <= 1:
        for t in tasks:
            done(t.index, run_task(t))
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(run_task, t): t.index for t in tasks}
            for fut, i in futures.items():
                done(i, fut.result())
    return [r for r in records if r is not None]


def make_tasks(clips: list[str], codecs: list[str], targets: list[str], frames: int | None,
               timeout: float) -> list[Task]:
    """Tasks in output order: clip, then codec, then target."""
    out = []
    for clip in clips:
        for codec in codecs:
            for target in targets:
                if target in MARKER_ONLY and Path(clip).suffix.lower() in (".bvh", ".amc"):
                    continue
                out.append(Task(len(out), clip, codec, target, frames, timeout))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--clips", default=None,
                    help="comma-separated: CMU takes (09_06), paths under ../shared/data, cmu14, others, every")
    ap.add_argument("--codecs", default=",".join(CODECS), help=f"comma-separated lossy codecs ({','.join(CODECS)})")
    ap.add_argument("--targets", default=",".join(DEFAULT_TARGETS),
                    help=f"comma-separated ({','.join(TARGETS)}; default {','.join(DEFAULT_TARGETS)})")
    ap.add_argument("--quick", action="store_true", help=f"the {len(QUICK_CLIPS)} quick clips, first "
                    f"{QUICK_FRAMES} frames (unless --clips / --frames say otherwise)")
    ap.add_argument("--frames", type=int, default=None, help="keep only the first N frames of every clip")
    ap.add_argument("--jobs", type=int, default=1, help="processes (output order does not depend on it)")
    ap.add_argument("--timeout", type=float, default=None, help="seconds per codec call (default 900, quick 120)")
    ap.add_argument("--out", type=Path, default=OUT, help="markdown report (default docs/benchmarks/quality.md)")
    ap.add_argument("--json", type=Path, default=None, help="also write every record as JSON")
    ap.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    args = ap.parse_args(argv)
    codecs = [c.strip().lower() for c in args.codecs.split(",") if c.strip()]
    for c in codecs:
        if not get_codec(c).lossy:
            raise SystemExit(f"--codecs: {c} is not a lossy codec")
    targets = [t.strip() for t in args.targets.split(",") if t.strip()]
    bad = [t for t in targets if t not in TARGETS]
    if bad:
        raise SystemExit(f"--targets: unknown {', '.join(bad)} (known: {', '.join(TARGETS)})")
    clips = resolve_clips(args.clips, args.quick)
    frames = args.frames if args.frames is not None else (QUICK_FRAMES if args.quick else None)
    timeout = args.timeout if args.timeout is not None else (120.0 if args.quick else 900.0)
    command = "python scripts/quality.py " + " ".join(argv if argv is not None else sys.argv[1:])
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    mach = machine()
    t0 = time.perf_counter()
    records = run_tasks(make_tasks(clips, codecs, targets, frames, timeout), max(1, args.jobs), not args.quiet)
    run = {"command": command.strip(), "started": started, "duration_s": time.perf_counter() - t0,
           "machine": mach, "mocapz_version": mocapz.__version__, "frames_cap": frames, "jobs": args.jobs,
           "timeout_s": timeout, "codecs": codecs, "targets": targets, "clips": [clip_id(c) for c in clips]}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(render(records, run), encoding="utf-8")
    if args.json:
        args.json.write_text(json.dumps({"run": run, "records": records}, indent=1, default=str), encoding="utf-8")
    print("\n".join(summary(records, run)))
    print(f"\nwrote {args.out}" + (f" and {args.json}" if args.json else ""), file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
