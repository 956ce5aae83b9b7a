"""Peak memory of the whole ``mocapz compress`` command per codec and target (issue 12: under 300 MB for a
5,000-frame clip, with any codec and target, growing at most linearly with the clip).

Each case is one ``mocapz compress CLIP -o OUT --codec C [options]`` process, as a user runs it (reading the file,
encoding, decoding and verifying every frame, writing). Its peak resident set is the kernel's own figure
(``ru_maxrss`` of the finished child, :func:`os.wait4`); its private (anonymous) and file-backed resident memory
are sampled from ``/proc/PID/status`` (``RssAnon``, ``RssFile``) every 2 ms, largest sample kept. The file-backed
part is mostly shared libraries' pages (numba's LLVM library above all, where numba is loaded: not with the kernels
compiled ahead of time, ``make kernels``) and depends on what the page cache holds:
the private part is the one a second process would add. Every case runs ``--repeat`` times (default 2); the table
gives the largest of the runs. Linux only (``/proc``).

Usage::

    .venv/bin/python scripts/memory.py                       # 06_13 (4,906 frames), every case; the 10-minute clip
    .venv/bin/python scripts/memory.py --clip 09_06 --no-long --out /tmp/m.md

Writes docs/benchmarks/memory.md (or --out) and prints it.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "benchmarks" / "memory.md"
GOAL_MB = 300
SAMPLE_S = 0.002
#: (codec, options) of every case: each lossy codec at its default target (max error 1 cm, feet held) and with
#: the other targets and the largest effort
CASES: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("lossless", ()),
    ("quant", ()), ("quant", ("--max-distortion", "1")), ("quant", ("--effort", "best")),
    ("pga", ()), ("pga", ("--max-distortion", "0.36")), ("pga", ("--max-arms", "0.5cm")), ("pga", ("--effort", "best")),
    ("patterns", ()), ("patterns", ("--max-distortion", "1")), ("patterns", ("--effort", "best")),
)
LONG_CODECS = ("lossless", "quant")  # the 10-minute clip's cases (its pga and patterns encodes take minutes)


def _status(pid: int) -> dict[str, float]:
    """``RssAnon`` and ``RssFile`` of a live process, MB (empty once it has gone)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            return {k: int(v.split()[0]) / 1024 for k, v in (ln.split(":", 1) for ln in f if ":" in ln)
                    if k in ("RssAnon", "RssFile")}
    except (OSError, ValueError):
        return {}


def run(cmd: list[str]) -> dict[str, float]:
    """One command: its peak resident MB (``ru_maxrss``), the largest sampled private and file-backed MB, and its
    wall time in seconds; raises RuntimeError if it fails."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    peak = {"RssAnon": 0.0, "RssFile": 0.0}
    done = threading.Event()

    def sample() -> None:
        while not done.is_set():
            for k, v in _status(proc.pid).items():
                peak[k] = max(peak[k], v)
            time.sleep(SAMPLE_S)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    err = proc.stderr.read() if proc.stderr else b""  # until it closes: the process has finished
    _, status, usage = os.wait4(proc.pid, 0)
    done.set()
    sampler.join()
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise RuntimeError(f"{' '.join(cmd)}: exit {proc.returncode}: {err.decode(errors='replace').strip()[-300:]}")
    return {"rss": usage.ru_maxrss / 1024, "anon": peak["RssAnon"], "file": peak["RssFile"],
            "s": time.perf_counter() - t0}


def measure(clip: Path, cases: tuple[tuple[str, tuple[str, ...]], ...], repeat: int, tmp: Path) -> list[dict]:
    """Every case on ``clip``: the largest of ``repeat`` runs of each figure (time: the smallest)."""
    rows = []
    exe = [sys.executable, "-m", "mocapz"]
    for codec, options in cases:
        runs = [run([*exe, "compress", str(clip), "-o", str(tmp / "out.mcz"), "-f", "-q", "--codec", codec, *options])
                for _ in range(repeat)]
        default = "(exact)" if codec == "lossless" else "(default target)"
        rows.append({"clip": clip.stem, "codec": codec, "options": " ".join(options) or default,
                     **{k: max(r[k] for r in runs) for k in ("rss", "anon", "file")}, "s": min(r["s"] for r in runs)})
        print(f"{clip.stem} {codec} {' '.join(options)}: {rows[-1]}", file=sys.stderr)
    return rows


def _frames(clip: Path) -> int:
    import mocapz  # noqa: PLC0415

    return mocapz.load(clip).n_frames


def render(rows: list[dict], frames: dict[str, int], command: str, started: str, minutes: float) -> str:
    from mocapz import aot  # noqa: PLC0415

    lines = ["# Peak memory of the whole command (issue 12)", "",
             f"Written by `{command}` on {started} in {minutes:.0f} min; {platform.processor() or platform.machine()}, "
             f"Python {platform.python_version()}. See the script's docstring: one `mocapz compress` process a case "
             "(read, encode, decode and verify every frame, write), the largest of its runs. *Peak resident* is the "
             "kernel's figure for the finished process; *private* and *file-backed* are the largest samples of its "
             "anonymous and file-mapped resident memory (every 2 ms; their largest need not fall at the same instant). "
             "File-backed pages are mostly shared libraries (numba's LLVM library: 75-100 MB once numba is loaded; "
             f"compiled kernels here: {aot.in_use()}) and count only where the page cache holds them; the private "
             "memory is what a second process adds. "
             f"Issue 12 asks for under {GOAL_MB} MB for a 5,000-frame clip with any codec and target.", "",
             "| clip | frames | codec | options | peak resident MB | private MB | file-backed MB | time s |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['clip']} | {frames[r['clip']]:,} | {r['codec']} | {r['options']} | {r['rss']:.0f} | "
                     f"{r['anon']:.0f} | {r['file']:.0f} | {r['s']:.2f} |")
    own = [r for r in rows if r["clip"] == rows[0]["clip"]]
    worst = max(own, key=lambda r: r["rss"])
    lines += ["", f"{rows[0]['clip']}: the largest peak resident set is {worst['rss']:.0f} MB ({worst['codec']}, "
              f"{worst['options']}; {GOAL_MB} MB asked), the largest private memory "
              f"{max(r['anon'] for r in own):.0f} MB.", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clip", default="06_13", help="a CMU BVH clip of ../shared/data/cmu/bvh (default 06_13)")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--no-long", action="store_true", help="leave out the 10-minute synthetic clip")
    ap.add_argument("--codecs", default=None, help="only these codecs (comma-separated)")
    ap.add_argument("--out", type=Path, default=OUT)
    argv = sys.argv[1:] if argv is None else argv
    args = ap.parse_args(argv)
    from mocapz.bench.corpus import default_data_dir  # noqa: PLC0415

    clip = default_data_dir() / "cmu" / "bvh" / f"{args.clip}.bvh"
    keep = None if args.codecs is None else set(args.codecs.split(","))
    cases = tuple(c for c in CASES if keep is None or c[0] in keep)
    t0, started = time.time(), time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        rows = measure(clip, cases, args.repeat, tmp)
        frames = {clip.stem: _frames(clip)}
        if not args.no_long:
            sys.path.insert(0, str(Path(__file__).resolve().parent))
            import speed  # noqa: PLC0415  (the 10-minute clip of speed.md)

            long = speed.synthetic_clip(tmp)
            rows += measure(long, tuple(c for c in cases if c[0] in LONG_CODECS and not c[1]), args.repeat, tmp)
            frames[long.stem] = _frames(long)
    command = " ".join(["scripts/memory.py", *argv])
    text = render(rows, frames, command, started, (time.time() - t0) / 60)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
