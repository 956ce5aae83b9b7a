"""Speed benchmark (issue 12): encode (fixed settings and with a target), full decode, the whole
``mocapz compress`` command, seek (a 20-frame range) and the size cost of blocks, per codec, as frames/s and as
a multiple of the lossless codec in the same run.

Clips: the CMU BVH clips of ../shared/data/cmu/bvh (``--quick``: 3 of them) and a synthetic 10-minute clip
(72,000 frames at 120 fps: the motion frames of 06_13 played forwards and backwards until long enough, so
the motion stays continuous). Every measurement runs in its own process (``--worker``), on one thread
(``OPENBLAS_NUM_THREADS=1`` and friends), and reports its peak resident memory (``ru_maxrss``: the Python
interpreter, numpy/scipy and the loaded clip included). A call that runs over ``--time-limit`` seconds is
stopped and reported as such.

Seek and blocks (its own process per codec and clip, ``mode="seek"``): the clip is compressed at the fixed
settings with the codec's default blocks, with ``block="1s"``, ``block="4s"`` and ``block=0`` (one block). For
the default and the 1-s file: the full decode and ``decompress(data, frames=slice(a, a + 20))`` at 5 starts
``a`` spread evenly from the first frame to the last 20, timed in interleaved rounds (the full decode, then
the 5 seeks; at least ``--repeat`` rounds, more while they fill 0.5 s, at most 20), each call's best kept; the
seek is the median of the 5, reported as frames/s of the 20 frames and as a percentage of the full decode of
the same file; the same 5 ranges are also read from a reader opened once (``mocapz.open(data)[a:a + 20]``: the
file's container, checksum, layout and blocks read before the rounds; it keeps what a lossy clip's windows
share, found by the rounds after the first), in the same rounds (default blocks: "% with an open reader"). Block
cost: the size of the 1-s and the 4-s file over the one-block file, minus 1, in %. That
process is stopped after ``--time-limit * (4 * --repeat + 6) + 60`` seconds.

Encode with each target: the whole ``mocapz compress`` of each CMU clip measured with each of :data:`TARGETS`
(one command a clip, best of ``--repeat``), beside the default target's column.

A library in one command (with two CMU clips or more): ``mocapz compress CLIPS... -o DIR`` over all the CMU
clips measured, per codec, serially on one thread (start-up, and numba's loading without the ahead-of-time
kernels, paid once), best of ``--repeat``.

Usage::

    .venv/bin/python scripts/speed.py                    # every CMU clip + the 10-minute clip, every codec
    .venv/bin/python scripts/speed.py --quick            # 3 clips + the 10-minute clip
    .venv/bin/python scripts/speed.py --clips 09_06,06_13 --codecs lossless,pga --repeat 3 --out /tmp/s.md
    .venv/bin/python scripts/speed.py --clips 05_02 --codecs lossless,quant --repeat 1 --no-synthetic --out /tmp/s.md

Writes docs/benchmarks/speed.md (or --out) and prints it.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from contextlib import AbstractContextManager as ContextManager
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
OUT = ROOT / "docs" / "benchmarks" / "speed.md"
CODECS = ("lossless", "quant", "pga", "patterns", "subsample", "pca", "segpca")
FIXED: dict[str, dict[str, Any]] = {"pga": {"geodesics": 16}}  # fixed settings: the defaults, pga at 16 geodesics
TARGET = {"max_error": "1cm"}
# the other targets' whole commands (CMU clips, one command a clip): the distortion of the papers' tables and an ARMS
TARGETS: dict[str, list[str]] = {"max distortion 0.36 %": ["--max-distortion", "0.36"],
                                 "max ARMS 5 mm": ["--max-arms", "5mm"]}
QUICK = ("09_06", "12_01", "02_05")
SYNTH_SOURCE, SYNTH_FRAMES = "06_13", 72_000
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
SEEK_FRAMES, SEEK_STARTS = 20, 5  # seek: 20-frame ranges at 5 starts spread over the clip
BLOCKS: dict[str, int | str | None] = {"default": None, "1s": "1s", "4s": "4s", "one": 0}  # block= of each file
SEEKED = ("default", "1s")  # the files whose seek is timed
WARM_FRAMES = 600  # warm_up: frames of the clip coded before the timings (numba and the kernels loaded)
ROUNDS_FILL_S, MAX_ROUNDS = 0.5, 20  # seek: more rounds than --repeat while they fill 0.5 s


# ---------------------------------------------------------------- worker (one measurement, own process)

def worker(spec: dict[str, Any]) -> dict[str, Any]:
    """Load the clip, time the codec calls ``spec`` asks for (seconds, best of ``repeat``), report memory."""
    import mocapz  # noqa: PLC0415  (first: pins the BLAS kernels)

    motion = mocapz.load(spec["path"])
    out: dict[str, Any] = {"frames": motion.n_frames, "rss_loaded_mb": _rss_mb()}
    opts = dict(FIXED.get(spec["codec"], {}))
    target = spec["mode"] == "target" or spec.get("target", False)
    out["numba"] = warm_up(motion, spec["codec"], TARGET if target else opts)
    if spec["mode"] == "compile":
        return out
    if spec["mode"] == "seek":
        return {**out, **seek_worker(motion, spec["codec"], opts, spec["repeat"]), "rss_peak_mb": _rss_mb()}
    if spec["mode"] == "target":
        t = time.perf_counter()
        data = mocapz.compress(motion, codec=spec["codec"], **TARGET)
        out["encode_target_s"] = time.perf_counter() - t
    else:
        enc = []
        for _ in range(spec["repeat"]):
            t = time.perf_counter()
            data = mocapz.compress(motion, codec=spec["codec"], **opts)
            enc.append(time.perf_counter() - t)
        out.update(encode_s=min(enc), decode_s=decode_timing(data, spec["repeat"]))
    out.update(bytes=len(data), rss_peak_mb=_rss_mb())
    return out


def warm_up(motion: Any, codec: str, opts: dict[str, Any]) -> bool:
    """Load the kernels ``codec`` uses, untimed: a round trip of the clip's first :data:`WARM_FRAMES` frames with
    the options about to be timed. The timings are then those of a process that has coded a long clip already (a
    library, a batch): with numba's just-in-time kernels, loading numba and its cache (about half a second, once
    per process) is left out, and their lazy loading no longer leaves a short clip on the NumPy path (the same
    bytes and values either way); the kernels compiled ahead of time (:mod:`mocapz.aot`) cost nothing to load.
    The whole command's column keeps the cold start. Returns whether compiled kernels are used."""
    import importlib.util  # noqa: PLC0415

    import mocapz  # noqa: PLC0415
    from mocapz import aot  # noqa: PLC0415

    if aot.extension() is None and importlib.util.find_spec("numba") is None:
        return False
    part = motion.slice(0, min(motion.n_frames, WARM_FRAMES))
    data = mocapz.compress(part, codec=codec, **opts)
    mocapz.decompress(data)
    mocapz.decompress(data, frames=slice(0, min(SEEK_FRAMES, part.n_frames)))
    return True


def seek_starts(frames: int, length: int = SEEK_FRAMES, count: int = SEEK_STARTS) -> list[int]:
    """``count`` first frames of ``length``-frame ranges spread evenly from the clip's start to its end."""
    last = max(frames - length, 0)
    return sorted({round(i * last / (count - 1)) for i in range(count)}) if count > 1 else [0]


def seek_worker(motion: Any, codec: str, opts: dict[str, Any], repeat: int) -> dict[str, Any]:
    """Every file of ``BLOCKS`` (bytes, encode seconds, its blocks); for those of ``SEEKED`` also the full decode
    and the seek (median over the starts of the best of ``repeat`` of ``decompress(frames=slice(a, a + 20))``)."""
    import mocapz  # noqa: PLC0415
    from mocapz.format import blocks  # noqa: PLC0415
    from mocapz.format.container import Container  # noqa: PLC0415

    n = motion.n_frames
    out: dict[str, Any] = {"frame_rate": motion.frame_rate}
    for label, block in BLOCKS.items():
        t = time.perf_counter()
        data = mocapz.compress(motion, codec=codec, block=block, **opts)
        rec: dict[str, Any] = {"encode_s": time.perf_counter() - t, "bytes": len(data)}
        box = Container.from_bytes(data)
        if box.blocked:
            index = blocks.unpack(box.sections, n)[0]
            rec.update(blocks=index.count, block_frames=index.block_frames)
        else:
            rec.update(blocks=1, block_frames=n)
        if label in SEEKED:
            length = min(SEEK_FRAMES, n)
            mocapz.decompress(data, frames=slice(0, length))  # untimed: lazy imports, caches
            starts = seek_starts(n, length)
            decode_s, times, opened, rounds = seek_timings(data, starts, length, repeat)
            rec.update(decode_s=decode_s, seek_frames=length, seek_starts=starts, seek_all_s=times,
                       seek_s=statistics.median(times), reader_all_s=opened,
                       reader_s=statistics.median(opened), rounds=rounds)
        out[label] = rec
    return out


def seek_timings(data: bytes, starts: list[int], length: int, repeat: int
                 ) -> tuple[float, list[float], list[float], int]:
    """The full decode of ``data`` and the decode of ``length`` frames at every start, by ``decompress(frames=)``
    and by a reader opened once (``mocapz.open(data)[a:b]``, the file read and checked before the rounds), timed
    in rounds (each round: the full decode, then every start each way), at least ``repeat`` rounds and more while
    they fill ``ROUNDS_FILL_S`` (at most ``MAX_ROUNDS``): ``(best full decode, best of every start, best of every
    start with the reader, rounds)`` in seconds. Interleaved so that a slow spell of a shared machine weighs on
    all of them alike."""
    import mocapz  # noqa: PLC0415

    reader = mocapz.open(data)
    ranges = [None, *(slice(a, a + length) for a in starts)]
    calls = [(lambda f=f: mocapz.decompress(data, frames=f)) for f in ranges] \
        + [(lambda f=f: reader[f]) for f in ranges[1:]]
    best = [float("inf")] * len(calls)
    rounds, t0 = 0, time.perf_counter()
    while rounds < repeat or (rounds < MAX_ROUNDS and time.perf_counter() - t0 < ROUNDS_FILL_S):
        for i, call in enumerate(calls):
            t = time.perf_counter()
            part = call()
            best[i] = min(best[i], time.perf_counter() - t)
            if i and part.n_frames != length:
                raise RuntimeError(f"a seek of {length} frames gave {part.n_frames} frames")
        rounds += 1
    return best[0], best[1:len(ranges)], best[len(ranges):], rounds


def decode_timing(data: bytes, repeat: int) -> float:
    """The best time of a full ``decompress(data)``, decoded again and again (a library decoded clip after clip):
    at least ``repeat`` times and more while they fill ``ROUNDS_FILL_S`` (at most ``MAX_ROUNDS``), as the seek's
    rounds."""
    import mocapz  # noqa: PLC0415

    best, rounds, t0 = float("inf"), 0, time.perf_counter()
    while rounds < repeat or (rounds < MAX_ROUNDS and time.perf_counter() - t0 < ROUNDS_FILL_S):
        t = time.perf_counter()
        mocapz.decompress(data)
        best = min(best, time.perf_counter() - t)
        rounds += 1
    return best


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: kilobytes


# ---------------------------------------------------------------- parent: run the workers, time the CLI

def run_worker(spec: dict[str, Any], limit: float) -> dict[str, Any]:
    """One measurement in a fresh process; ``{"over": limit}`` when it runs over ``limit`` seconds."""
    env = {**os.environ, **ONE_THREAD}
    cmd = [sys.executable, __file__, "--worker", json.dumps(spec)]
    try:
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=limit, env=env, check=False)
    except subprocess.TimeoutExpired:
        return {"over": limit}
    if res.returncode != 0:
        return {"error": (res.stderr.strip().splitlines() or ["?"])[-1][:160]}
    return json.loads(res.stdout.strip().splitlines()[-1])


def compile_bytecode() -> None:
    """Compile mocapz's modules to bytecode (``__pycache__``), as pip does when it installs a package: a machine
    that sets PYTHONDONTWRITEBYTECODE (this one does) would otherwise compile every module in every command."""
    import compileall

    import mocapz

    compileall.compile_dir(str(Path(mocapz.__file__).parent), quiet=1)


def run_cli(path: Path, codec: str, repeat: int, limit: float, tmp: Path, flags: list[str] | None = None
            ) -> dict[str, Any]:
    """Wall time (best of ``repeat``) of the whole command ``mocapz compress`` (start-up and file read included),
    with the codec's fixed options and ``flags`` (a target)."""
    return _command_time([path], lambda: contextlib.nullcontext(str(tmp / f"cli.{codec}.mcz")), codec, repeat, limit,
                         flags)


def run_targets(paths: list[Path], codecs: list[str], repeat: int, limit: float) -> dict[str, dict[str, Any]]:
    """Per lossy codec and :data:`TARGETS` label: ``{"cli_s": the one-clip commands' times added up}`` over
    ``paths`` (each best of ``repeat``), or the first clip's ``{"over"}`` / ``{"error"}``."""
    out: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory() as td:
        for codec in codecs:
            if codec == "lossless":
                continue
            for label, flags in TARGETS.items():
                total: dict[str, Any] = {"cli_s": 0.0}
                for path in paths:
                    got = run_cli(path, codec, repeat, limit + 30, Path(td), flags)
                    if "cli_s" not in got:
                        total = got
                        break
                    total["cli_s"] += got["cli_s"]
                out.setdefault(codec, {})[label] = total
                print(f"targets {codec} {label}: {json.dumps(total)}", file=sys.stderr, flush=True)
    return out


def targets_table(rows: list[dict[str, Any]], targets: dict[str, dict[str, Any]]) -> list[str]:
    """The *encode with each target* table: frames/s of the one-clip commands over the CMU clips (their times added
    up) at the default target (column `mocapz compress`) and at each of :data:`TARGETS`, ``x`` over the lossless
    codec's one-clip commands."""
    frames = sum(r["frames"] for r in rows if r["codec"] == "lossless" and r["frames"])
    ref = sum(r["cli"].get("cli_s") or 0.0 for r in rows if r["codec"] == "lossless") or None

    def cell(m: dict[str, Any]) -> str:
        fps = _fps(frames, m.get("cli_s"))
        return _failed(m) or (f"{fps:,.0f}" + (f" x{ref / m['cli_s']:.2f}" if ref else "") if fps else "-")

    lines = ["| codec | frames | max error 1 cm (the default) | " + " | ".join(TARGETS) + " |",
             "|---|---|---|" + "---|" * len(TARGETS)]
    for codec, by_target in targets.items():
        mine = [r["cli"].get("cli_s") for r in rows if r["codec"] == codec]
        default = {"cli_s": sum(mine)} if mine and all(mine) else {}
        lines.append(f"| {codec} | {frames:,} | {cell(default)} | "
                     + " | ".join(cell(by_target.get(t, {})) for t in TARGETS) + " |")
    return lines


def run_library(paths: list[Path], codec: str, repeat: int, limit: float) -> dict[str, Any]:
    """Wall time (best of ``repeat``) of one ``mocapz compress CLIPS... -o DIR`` over every clip (a library
    compressed in one command, serially: start-up and numba's loading paid once, every file read included)."""
    return _command_time(paths, tempfile.TemporaryDirectory, codec, repeat, limit)


def _command_time(paths: list[Path], output: Callable[[], ContextManager[str]], codec: str, repeat: int,
                  limit: float, extra: list[str] | None = None) -> dict[str, Any]:
    """``{"cli_s": best wall time}`` of ``mocapz compress PATHS... -o OUT`` (``output()`` gives OUT for each run)
    with the codec's fixed options and ``extra`` flags, on one thread; or ``{"over": limit}``, ``{"error": its last
    line}``."""
    exe = Path(sys.executable).parent / "mocapz"
    flags = [f"--{k.replace('_', '-')}={v}" for k, v in FIXED.get(codec, {}).items()] + (extra or [])
    best = None
    for _ in range(repeat):
        with output() as out:
            cmd = [str(exe), "compress", *map(str, paths), "-o", out, "--codec", codec, "-f", "-q", *flags]
            t = time.perf_counter()
            try:
                res = subprocess.run(cmd, capture_output=True, text=True, timeout=limit, check=False,
                                     env={**os.environ, **ONE_THREAD})
            except subprocess.TimeoutExpired:
                return {"over": limit}
            if res.returncode != 0:
                return {"error": (res.stderr.strip().splitlines() or ["?"])[-1][:160]}
            dt = time.perf_counter() - t
        best = dt if best is None else min(best, dt)
    return {"cli_s": best}


def library_table(rows: list[dict[str, Any]], library: dict[str, Any]) -> list[str]:
    """The *library in one command* table: frames/s of each codec's one command over the clips (``x``: over the
    lossless codec's) beside its one-clip commands' (their times added up, where every one finished)."""
    frames = sum(r["frames"] for r in rows if r["codec"] == "lossless" and r["frames"])

    def fps_cell(seconds: float | None, ref_s: float | None) -> str:
        fps = _fps(frames, seconds)
        return f"{fps:,.0f}" + (f" x{ref_s / seconds:.2f}" if ref_s and seconds else "") if fps else "-"

    def per_clip(codec: str) -> float | None:
        mine = [r["cli"].get("cli_s") for r in rows if r["codec"] == codec]
        return sum(mine) if mine and all(mine) else None

    ref, ref_one = library.get("lossless", {}).get("cli_s"), per_clip("lossless")
    lines = ["| codec | clips | frames | one command, all the clips | one command a clip |", "|---|---|---|---|---|"]
    for codec, m in library.items():
        cell = _failed(m) or fps_cell(m.get("cli_s"), ref)
        lines.append(f"| {codec} | {len({r['clip'] for r in rows})} | {frames:,} | {cell} | "
                     f"{fps_cell(per_clip(codec), ref_one)} |")
    return lines


def synthetic_clip(tmp: Path) -> Path:
    """Write the 10-minute clip (SYNTH_FRAMES frames, ping-pong of SYNTH_SOURCE's motion frames) as a BVH."""
    import numpy as np  # noqa: PLC0415

    import mocapz  # noqa: PLC0415

    m = mocapz.load(DATA / "cmu" / "bvh" / f"{SYNTH_SOURCE}.bvh")
    body = m.channels[1:]  # frame 0 is cgspeed's added T-pose
    loop = np.concatenate([body, body[::-1]])
    reps = -(-SYNTH_FRAMES // loop.shape[0])
    values = np.concatenate([loop] * reps)[:SYNTH_FRAMES]
    path = tmp / f"synthetic_10min_{SYNTH_SOURCE}.bvh"
    mocapz.save(m.with_values(values), path)
    return path


def measure(clips: list[tuple[str, Path]], codecs: list[str], repeat: int, limit: float) -> list[dict[str, Any]]:
    rows = []
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        for name, path in clips:
            if path is None:
                path = synthetic_clip(tmp)
            for codec in codecs:
                row: dict[str, Any] = {"clip": name, "codec": codec}
                row["fixed"] = run_worker({"path": str(path), "codec": codec, "mode": "fixed", "repeat": repeat},
                                          limit * 2 * repeat + 30)
                row["target"] = ({"na": True} if codec == "lossless" else
                                 run_worker({"path": str(path), "codec": codec, "mode": "target"}, limit + 30))
                row["cli"] = run_cli(path, codec, repeat, limit + 30, tmp)
                row["seek"] = run_worker({"path": str(path), "codec": codec, "mode": "seek", "repeat": repeat},
                                         limit * (4 * repeat + 6) + 60)
                row["frames"] = row["fixed"].get("frames") or row["target"].get("frames")
                rows.append(row)
                print(f"{name} {codec}: {json.dumps(row)}", file=sys.stderr, flush=True)
    return rows


# ---------------------------------------------------------------- report

def _fps(frames: int | None, seconds: float | None) -> float | None:
    return frames / seconds if frames and seconds else None


def _cell(row: dict[str, Any], what: str, ref: dict[str, Any] | None) -> str:
    """``frames/s (x lossless)`` of one measurement, or why there is none."""
    part, key = {"enc": ("fixed", "encode_s"), "dec": ("fixed", "decode_s"), "tgt": ("target", "encode_target_s"),
                 "cli": ("cli", "cli_s")}[what]
    m = row[part]
    why = _failed(m)
    if why:
        return why
    fps = _fps(m.get("frames", row["frames"]), m.get(key))
    text = f"{fps:,.0f}"
    if what == "dec":
        text += f" ({1e6 / fps:.0f} us)"
    if ref is not None:
        rpart, rkey = ("fixed", "encode_s") if what == "tgt" else (part, key)
        rfps = _fps(ref[rpart].get("frames", ref["frames"]), ref[rpart].get(rkey))
        if rfps:
            text += f" x{fps / rfps:.2f}"
    return text


def _mem(row: dict[str, Any]) -> str:
    peaks = [row[p].get("rss_peak_mb") for p in ("fixed", "target") if row[p].get("rss_peak_mb")]
    loaded = row["fixed"].get("rss_loaded_mb")
    return f"{max(peaks):.0f} ({loaded:.0f})" if peaks and loaded else "-"


def summarise(rows: list[dict[str, Any]], codecs: list[str]) -> list[dict[str, Any]]:
    """One row per codec over the CMU clips: frames / total seconds of the clips where the call finished."""
    out = []
    parts = {"fixed": ("encode_s", "decode_s"), "target": ("encode_target_s",), "cli": ("cli_s",)}
    for codec in codecs:
        mine = [r for r in rows if r["codec"] == codec and r["frames"]]
        if not mine:
            continue
        agg: dict[str, Any] = {"clip": "CMU clips", "codec": codec, "frames": sum(r["frames"] for r in mine)}
        for part, keys in parts.items():
            done = [r for r in mine if all(k in r[part] for k in keys)]
            if done:
                agg[part] = {k: sum(r[part][k] for r in done) for k in keys}
                agg[part]["frames"] = sum(r["frames"] for r in done)
            else:
                agg[part] = dict(mine[0][part])
        agg["over"] = sum("over" in r["target"] for r in mine) if agg["target"].get("frames") else 0
        agg["fixed"]["rss_peak_mb"] = max(max(r[p].get("rss_peak_mb", 0) for p in ("fixed", "target")) for r in mine)
        agg["fixed"]["rss_loaded_mb"] = max(r["fixed"].get("rss_loaded_mb", 0) for r in mine)
        out.append(agg)
    return out


def table(rows: list[dict[str, Any]], with_clip: bool) -> list[str]:
    head = ("| clip " if with_clip else "") + "| codec | frames | encode, fixed | encode, max error 1 cm | decode " \
        "| `mocapz compress` (whole command) | peak memory MB (after load) |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    refs = {r["clip"]: r for r in rows if r["codec"] == "lossless"}
    for r in rows:
        ref = refs.get(r["clip"])
        tgt = _cell(r, "tgt", ref)
        if r.get("over"):
            tgt += f" ({r['over']} clips over the limit, left out)"
        cells = [r["codec"], f"{r['frames'] or '-':,}" if r["frames"] else "-", _cell(r, "enc", ref), tgt,
                 _cell(r, "dec", ref), _cell(r, "cli", ref), _mem(r)]
        lines.append(("| " + r["clip"] + " " if with_clip else "") + "| " + " | ".join(cells) + " |")
    return lines


def _failed(m: dict[str, Any]) -> str | None:
    """Why a measurement has no figures (n/a, over the limit, an error), or None."""
    if m.get("na"):
        return "n/a"
    if "over" in m:
        return f"over {m['over']:.0f} s"
    if "error" in m:
        return "refused (TargetError)" if "TargetError" in m["error"] else f"error: {m['error']}"
    return None


def _pct(x: float) -> str:
    return f"{x:.1f} %" if abs(x) >= 1 else f"{x:.2f} %"


def _blocks_text(rec: dict[str, Any], frame_rate: float) -> str:
    if "blocks_text" in rec:
        return str(rec["blocks_text"])
    if rec["blocks"] <= 1:
        return "one block"
    return f"{rec['block_frames'] / frame_rate:g} s ({rec['blocks']} blocks)"


def _one_block(rec: dict[str, Any]) -> bool:
    """The file is one block (over several clips: every clip's)."""
    return bool(rec.get("one_block", rec["blocks"] <= 1))


def seek_fps(m: dict[str, Any], label: str) -> float | None:
    """Frames/s of the 20-frame seek in file ``label`` of a seek measurement (None: not measured)."""
    rec = m.get(label) or {}
    return _fps(rec.get("seek_frames"), rec.get("seek_s"))


def seek_pct(m: dict[str, Any], label: str, key: str = "seek_s") -> float | None:
    """The seek's time (``key``: by ``decompress(frames=)``, or ``reader_s``: by an open reader) as a percentage
    of the full decode of the same file."""
    rec = m.get(label) or {}
    return 100.0 * rec[key] / rec["decode_s"] if rec.get(key) and rec.get("decode_s") else None


def block_cost(m: dict[str, Any], label: str) -> float | None:
    """The size of file ``label`` over the one-block file's, minus 1, in percent."""
    one, rec = (m.get("one") or {}).get("bytes"), (m.get(label) or {}).get("bytes")
    return 100.0 * (rec / one - 1.0) if one and rec else None


def seek_cells(row: dict[str, Any], ref: dict[str, Any] | None) -> list[str]:
    """The seek table's cells of one row after clip, codec and frames."""
    m = row["seek"]
    why = _failed(m)
    if why:
        return [why] * 8
    cells = [_blocks_text(m["default"], m["frame_rate"])]
    for label in SEEKED:
        fps = seek_fps(m, label)
        text = f"{fps:,.0f}" if fps else "-"
        rfps = seek_fps(ref["seek"], "default") if ref is not None else None
        if fps and rfps:
            text += f" x{fps / rfps:.2f}"
        if label != "default" and _one_block(m[label]):
            text += " (one block)"
        pct = seek_pct(m, label)
        cells += [text, _pct(pct) if pct is not None else "-"]
        if label == "default":
            opened = seek_pct(m, label, "reader_s")
            cells.append(_pct(opened) if opened is not None else "-")
    for label in ("1s", "4s"):
        cost = block_cost(m, label)
        text = f"{cost:+.1f} %" if cost is not None else "-"
        cells.append(text + (" (one block)" if _one_block(m[label]) else ""))
    return cells


def summarise_seek(rows: list[dict[str, Any]], codecs: list[str]) -> list[dict[str, Any]]:
    """One row per codec over the CMU clips where the seek measurement finished: times and bytes added up."""
    out = []
    for codec in codecs:
        done = [r for r in rows if r["codec"] == codec and _failed(r["seek"]) is None]
        if not done:
            mine = [r for r in rows if r["codec"] == codec]
            if mine:
                out.append({"clip": "CMU clips", "codec": codec, "frames": None, "seek": dict(mine[0]["seek"])})
            continue
        agg: dict[str, Any] = {"frame_rate": done[0]["seek"]["frame_rate"]}
        for label in BLOCKS:
            recs = [r["seek"][label] for r in done]
            a: dict[str, Any] = {k: sum(rec[k] for rec in recs)
                                 for k in ("bytes", "blocks", "decode_s", "seek_s", "reader_s", "seek_frames")
                                 if k in recs[0]}
            lengths = sorted({round(rec["block_frames"] / r["seek"]["frame_rate"], 3)
                              for r, rec in zip(done, recs, strict=True) if rec["blocks"] > 1})
            a["one_block"] = not lengths
            a["blocks_text"] = f"{'/'.join(f'{x:g}' for x in lengths)} s ({a['blocks']} blocks)" if lengths \
                else "one block"
            agg[label] = a
        out.append({"clip": "CMU clips", "codec": codec, "frames": sum(r["seek"]["frames"] for r in done),
                    "seek": agg})
    return out


def seek_table(rows: list[dict[str, Any]], with_clip: bool) -> list[str]:
    head = ("| clip " if with_clip else "") + "| codec | frames | default blocks | seek 20 frames, default blocks " \
        "| % of a full decode | % with an open reader | seek 20 frames, 1-s blocks | % of a full decode " \
        "| size, 1-s blocks | size, 4-s blocks |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    refs = {r["clip"]: r for r in rows if r["codec"] == "lossless" and _failed(r["seek"]) is None}
    for r in rows:
        frames = f"{r['frames']:,}" if r["frames"] else "-"
        cells = [r["codec"], frames, *seek_cells(r, refs.get(r["clip"]))]
        lines.append(("| " + r["clip"] + " " if with_clip else "") + "| " + " | ".join(cells) + " |")
    return lines


def _with_seek(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows, each with a seek measurement (a run saved before seek was measured: "n/a")."""
    return [r if "seek" in r else {**r, "seek": {"na": True}} for r in rows]


def render(rows: list[dict[str, Any]], codecs: list[str], args: argparse.Namespace, started: str,
           info: dict[str, Any], wall: float, library: dict[str, Any] | None = None,
           targets: dict[str, dict[str, Any]] | None = None) -> str:
    cmu = [r for r in rows if r["clip"] != "synthetic 10 min"]
    synth = [r for r in rows if r["clip"] == "synthetic 10 min"]
    lines = [
        "# Speed (issue 12)", "",
        f"Written by `scripts/speed.py {' '.join(args.argv)}` on {started} in {wall / 60:.0f} min. "
        f"Machine: {info['cpu']}, {info['cores']} cores, load average {info['load_average_at_start']} at the "
        f"start (shared machine: compare the multiples, not the absolute figures); every measurement in its "
        f"own process on one thread, best of {args.repeat}.", "",
        "Cells: frames/s, then `xN` = that codec's frames/s over the lossless codec's in the same run on the "
        "same clips (encode with a target against lossless at fixed settings). Decode also gives us/frame. "
        f"Fixed settings: each codec's defaults ({', '.join(f'{c}: {o}' for c, o in FIXED.items())}); the "
        f"target is `max_error=1cm`, its process stopped after {args.time_limit + 30:.0f} s (\"over\": the "
        f"limit, {args.time_limit:.0f} s, plus 30 s for start-up and reading the clip). Encode and decode time "
        f"the library call on a loaded clip (file reading and writing excluded; encode best of {args.repeat}, "
        f"decode the best of the fixed-settings file decoded again and again: at least {args.repeat} times, more "
        f"while they fill {ROUNDS_FILL_S} s, at most {MAX_ROUNDS}, as a library's clips are decoded one after "
        f"the other), with "
        f"{info.get('kernels', 'numba')}, in a process that has loaded the codec's kernels first (an untimed "
        f"round trip of the clip's first {WARM_FRAMES} frames with the same options: a process that has coded a "
        "long clip already; otherwise numba's lazy loading leaves a short clip on the NumPy path, with the same "
        "bytes and values). Before any measurement, one process per codec and mode fills numba's on-disk cache, "
        "so that no measuring process compiles (without the ahead-of-time kernels, on a fresh checkout the first "
        "one would, at about 150 MB more); the whole command includes Python's start-up, loading numba where it "
        "pays (never with the ahead-of-time kernels) and reading the file, with mocapz's modules compiled to "
        "bytecode first, as an installed package has them (pip compiles them when it installs; this machine sets "
        "PYTHONDONTWRITEBYTECODE, which would otherwise make every command compile them, about 0.13 s). Memory: "
        "peak resident set of the measuring process (interpreter, numpy and the loaded clip included; the second "
        "figure is the same process after loading the clip, before any codec ran).", "",
        f"Seek and blocks (the tables *seek and blocks*, their own process per codec and clip): the clip is "
        f"compressed at the fixed settings with the codec's default blocks (`default blocks`: what the file "
        f"holds; the lossy codecs' default is one block, coded in the seekable layout from 1,024 frames, so "
        f"that a seek decodes the part of it the range needs), with "
        f"`block=\"1s\"`, `block=\"4s\"` and `block=0` (one block). Seek: `mocapz.decompress(data, "
        f"frames=slice(a, a + {SEEK_FRAMES}))` at {SEEK_STARTS} starts `a` spread evenly from the first frame "
        f"to the last {SEEK_FRAMES}, timed with the full decode of the same file in interleaved rounds (the "
        f"full decode, then the {SEEK_STARTS} seeks; at least {args.repeat} round{'s' * (args.repeat != 1)}, "
        f"more while they fill {ROUNDS_FILL_S:g} s, at most {MAX_ROUNDS}), each call's best kept; the seek is "
        f"the median of the {SEEK_STARTS}, as frames/s of the {SEEK_FRAMES} frames (`xN`: over the lossless "
        f"codec's seek with its default blocks, same clip) and as a percentage of that full decode. Reading "
        f"and checking the whole file (CRC-32, section table) is part of every seek. `% with an open reader`: "
        f"the same ranges in the same rounds from one `mocapz.open(data)` (the file read and checked once, "
        f"before the rounds); a reader keeps what the windows of a lossy clip in one block share (the "
        f"correction's running values chunk by chunk, its zstd-packed streams unpacked, pga's trajectories), so "
        f"the rounds after the first find these ranges' chunks decoded (a range in chunks no read has reached "
        f"yet costs about what `decompress(frames=)` costs). A clip shorter than two "
        f"blocks is coded as one block (\"(one block)\": so at 1-s blocks every clip under 2 s). Size: the "
        f"1-s and the 4-s file's bytes over the one-block file's, minus 1. Over the CMU clips, the times and "
        f"the bytes of the clips where the measurement finished are added up. That process is stopped after "
        f"{args.time_limit * (4 * args.repeat + 6) + 60:.0f} s.", "",
        "## Goals of issue 12", "",
        "| goal | where to read it |", "|---|---|",
        "| encode with a target >= 2,000 frames/s (pga, patterns), whole command | `mocapz compress` (the default "
        "target, max error 1 cm, feet held): one command a clip (column `mocapz compress`) and a library in one "
        "command (its table); the other targets: *encode with each target* |",
        "| encode at fixed settings >= 10,000 frames/s; lossless and quant >= 20,000 | `encode, fixed` |",
        "| decode >= 50,000 frames/s (<= 20 us/frame) every codec; <= 10 us lossless and quant | `decode` |",
        "| memory under 300 MB for a 5,000-frame clip | `peak memory` (06_13, 4,906 frames) |",
        f"| seek: {SEEK_FRAMES} frames of a 5,000-frame clip cost <= 5 % of a full decode | seek and blocks, "
        "`% of a full decode` (06_13, 4,906 frames; the 10-minute clip) |",
        "| blocks cost under 3 % of the size at the default block length | seek and blocks, `size, 1-s blocks` "
        "(the lossless codec's default; the lossy codecs default to one block) |", "",
    ]
    if cmu:
        lines += ["## CMU clips, all together", "", "Frames/s over the clips where the call finished.", ""]
        lines += table(summarise(cmu, codecs), with_clip=False) + [""]
        if library:
            lines += ["### A library in one command", "",
                      "`mocapz compress CLIPS... -o DIR --codec C` over all the CMU clips above in one command (a "
                      "library compressed serially, on one core: Python's start-up (and numba's loading, without the "
                      "ahead-of-time kernels) paid once, "
                      "every file read and written), with the same options as the column `mocapz compress`, best "
                      f"of {args.repeat}; frames/s, `xN` over the lossless codec's same command.", ""]
            lines += library_table(cmu, library) + [""]
        if targets:
            lines += ["### Encode with each target", "",
                      "The whole `mocapz compress CLIP --codec C` (start-up and file read included, one command a "
                      "clip, best of " f"{args.repeat} each, their times added up over the CMU clips above) at the "
                      "default target (the column `mocapz compress`) and with `" + "`, `".join(
                          " ".join(f) for f in TARGETS.values()) + "` (the correction's bound search; pga's own "
                      "rate search on clips of up to 300 frames); frames/s, `xN` over the lossless codec's "
                      "one-clip commands.", ""]
            lines += targets_table(cmu, targets) + [""]
        lines += ["### Seek and blocks, CMU clips all together", ""]
        lines += seek_table(summarise_seek(_with_seek(cmu), codecs), with_clip=False) + [""]
    if synth:
        lines += [f"## Synthetic 10-minute clip ({SYNTH_FRAMES:,} frames at 120 fps, {SYNTH_SOURCE} looped)", ""]
        lines += table(synth, with_clip=False) + [""]
        lines += ["### Seek and blocks, synthetic 10-minute clip", ""]
        lines += seek_table(_with_seek(synth), with_clip=False) + [""]
    if cmu:
        lines += ["## Per clip", ""] + table(cmu, with_clip=True) + [""]
        lines += ["### Seek and blocks, per clip", ""] + seek_table(_with_seek(cmu), with_clip=True) + [""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help=f"3 CMU clips ({', '.join(QUICK)}) + the 10-minute clip")
    ap.add_argument("--clips", help="comma-separated CMU clip names (e.g. 09_06,06_13); 'none' for no CMU clip")
    ap.add_argument("--no-synthetic", action="store_true", help="leave out the 10-minute clip")
    ap.add_argument("--codecs", default=",".join(CODECS), help="comma-separated codecs (lossless is always run)")
    ap.add_argument("--repeat", type=int, default=2, help="timings per measurement (the best is kept)")
    ap.add_argument("--time-limit", type=float, default=120.0, help="seconds before a target encode is stopped")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--render", type=Path, help="write the report again from a run's .json (no measuring)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(json.loads(args.worker))))
        return 0
    args.argv = sys.argv[1:] if argv is None else list(argv)
    if args.render:
        saved = json.loads(args.render.read_text())
        args.argv = saved.get("argv", args.argv)
        args.repeat, args.time_limit = saved.get("repeat", args.repeat), saved.get("time_limit", args.time_limit)
        codecs = saved.get("codecs") or list(dict.fromkeys(r["codec"] for r in saved["rows"]))
        started = saved.get("started", time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(args.render.stat().st_mtime)))
        text = render(saved["rows"], codecs, args, started, saved["machine"], saved.get("wall_s", 0.0),
                      saved.get("library"), saved.get("targets"))
        args.out.write_text(text + "\n", encoding="utf-8")
        print(text)
        return 0
    sys.path.insert(0, str(ROOT / "src"))
    from mocapz.bench.runner import machine  # noqa: PLC0415

    if args.clips:
        names = [] if args.clips == "none" else args.clips.split(",")
    else:
        names = list(QUICK) if args.quick else sorted(p.stem for p in (DATA / "cmu" / "bvh").glob("*.bvh"))
    clips: list[tuple[str, Path | None]] = [(n, DATA / "cmu" / "bvh" / f"{n}.bvh") for n in names]
    if not args.no_synthetic:
        clips.append(("synthetic 10 min", None))
    codecs = ["lossless"] + [c for c in args.codecs.split(",") if c and c != "lossless"]
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    info = machine()
    from mocapz import aot  # noqa: PLC0415

    info["kernels"] = {"ahead of time": "the kernels compiled ahead of time (`make kernels`: no numba loaded)",
                       "numba": "numba's just-in-time kernels (the ahead-of-time extension not built)",
                       "none": "no compiled kernels (the NumPy paths)"}[aot.in_use()]
    t0 = time.perf_counter()
    compile_bytecode()
    for codec in codecs:  # numba's on-disk cache filled first: no measuring process compiles (a fresh checkout would)
        for mode in ("fixed", "target"):
            run_worker({"path": str(DATA / "cmu" / "bvh" / f"{SYNTH_SOURCE}.bvh"), "codec": codec, "mode": "compile",
                        "target": mode == "target"}, args.time_limit)
    rows = measure(clips, codecs, args.repeat, args.time_limit)  # type: ignore[arg-type]
    cmu = [path for name, path in clips if path is not None]
    library = {codec: run_library(cmu, codec, args.repeat, args.time_limit * len(cmu) + 30)
               for codec in codecs} if len(cmu) > 1 else None
    targets = run_targets(cmu, codecs, args.repeat, args.time_limit) if cmu else None
    wall = time.perf_counter() - t0
    text = render(rows, codecs, args, started, info, wall, library, targets)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text + "\n", encoding="utf-8")
    saved = {"machine": info, "rows": rows, "codecs": codecs, "argv": args.argv, "repeat": args.repeat,
             "time_limit": args.time_limit, "started": started, "wall_s": wall, "library": library,
             "targets": targets}
    args.out.with_suffix(".json").write_text(json.dumps(saved, indent=1) + "\n", encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
