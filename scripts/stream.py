"""Streaming benchmark (issue 13): latency and memory of ``mocapz.StreamEncoder`` / ``StreamDecoder`` on a
synthetic hour-long stream, and the size of a stream against the offline file of the same frames.

The stream: the motion frames of CMU 06_13 (frame 0, cgspeed's T-pose, left out) played forwards and backwards
until ``--minutes`` of motion at 120 fps, fed to the encoder in chunks of 4 frames (1/30 s, a capture rig's
network packets). Per codec, in its own process (one thread):

* **latency**: for every block, the time from the write that completed it to its bytes (its encoding time:
  the stream's delay is the block length plus this); median and maximum;
* **memory**: peak resident memory (``ru_maxrss``) after the first minute, at the end of the stream and after
  decoding it (the stream's bytes go to a temporary file, as a recorder's would, and are read back in 64 kB
  chunks): bounded memory means the three are about equal, whatever the length;
* **decoder**: the stream's bytes fed back in 64 kB chunks to ``StreamDecoder``, time per block and the
  frames/s;
* **size**: the stream against ``mocapz.compress`` of the first ``--offline-frames`` frames (offline file, one
  block for lossy codecs, 1-s blocks for lossless) and against the stream of the same frames.

Usage::

    .venv/bin/python scripts/stream.py                        # 60 minutes, lossless and quant
    .venv/bin/python scripts/stream.py --minutes 2 --codecs lossless --out /tmp/stream.md

Writes docs/benchmarks/stream.md (or --out) and prints it.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
LOADING = {"ahead of time": "the kernels compiled ahead of time: nothing to load",
           "numba": "numba's just-in-time kernels, about 100 MB, are loaded once a process has coded or decoded "
                    "enough to pay for them",
           "none": "no compiled kernels: the NumPy paths"}
DATA = ROOT.parent / "shared" / "data"
OUT = ROOT / "docs" / "benchmarks" / "stream.md"
SOURCE = "06_13"
RATE = 120.0
CHUNK = 4
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def worker(codec: str, minutes: float, offline_frames: int) -> dict[str, Any]:
    """Stream ``minutes`` of motion through the codec; the figures of the module docstring."""
    import mocapz  # noqa: PLC0415, I001  (first: pins the BLAS kernels)
    import numpy as np  # noqa: PLC0415

    m = mocapz.load(DATA / "cmu" / "bvh" / f"{SOURCE}.bvh")
    body = m.channels[1:]
    loop = np.concatenate([body, body[::-1]])
    total = int(minutes * 60 * RATE)
    enc = mocapz.StreamEncoder(m, codec)
    latencies: list[float] = []
    out = tempfile.TemporaryFile()  # the stream goes to a file, as a recorder's would: not held in memory
    size = 0
    rss_first = None
    t0 = time.perf_counter()
    for start in range(0, total, CHUNK):
        idx = np.arange(start, min(start + CHUNK, total)) % len(loop)
        t = time.perf_counter()
        got = enc.write(loop[idx])
        if got and start:  # a block completed by this write (the first write also carries the header)
            latencies.append(time.perf_counter() - t)
        out.write(got)
        size += len(got)
        if rss_first is None and start >= 60 * RATE:
            rss_first = _rss_mb()
    last = enc.close()
    out.write(last)
    size += len(last)
    encode_s = time.perf_counter() - t0
    rss_end = _rss_mb()
    out.seek(0)
    dec = mocapz.StreamDecoder()
    frames, dec_lat, rss_dec_first = 0, [], None
    t0 = time.perf_counter()
    while chunk := out.read(65536):
        if rss_dec_first is None and frames >= 60 * RATE:
            rss_dec_first = _rss_mb()
        t = time.perf_counter()
        blocks = dec.feed(chunk)
        if blocks:
            dec_lat.append((time.perf_counter() - t) / len(blocks))
        frames += sum(b.n_frames for b in blocks)
    decode_s = time.perf_counter() - t0
    rss_decoded = _rss_mb()
    assert dec.complete and frames == total, (frames, total)
    n = min(offline_frames, total)
    idx = np.arange(n) % len(loop)
    ref = m.with_values(loop[idx])
    offline = len(mocapz.compress(ref, codec))
    enc2 = mocapz.StreamEncoder(m, codec)
    short = len(enc2.write(loop[idx]) + enc2.close())
    lat = np.array(latencies) * 1e3
    return {"codec": codec, "frames": total, "minutes": minutes, "bytes": size, "rss_decoded_mb": rss_decoded,
            "rss_decoded_first_minute_mb": rss_dec_first,
            "ratio": total * m.skeleton.n_channels * 4 / size, "encode_fps": total / encode_s,
            "latency_median_ms": float(np.median(lat)), "latency_max_ms": float(lat.max()),
            "block_s": float(enc.block / RATE), "rss_first_minute_mb": rss_first, "rss_end_mb": rss_end,
            "decode_fps": total / decode_s, "decode_block_ms_median": float(np.median(dec_lat) * 1e3),
            "offline_frames": n, "offline_bytes": offline, "stream_bytes_same_frames": short}


def _mb(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.0f}"


def render(rows: list[dict[str, Any]], command: str) -> str:
    from mocapz import aot  # noqa: PLC0415

    lines = ["# Streaming: latency and memory on an hour-long stream", "",
             f"Written by `{command}` ({time.strftime('%Y-%m-%d')}, a shared 2-core machine, one thread per "
             "codec). See the script's docstring for what is measured.", "",
             "| codec | minutes | frames | block | ratio | encode frames/s | block latency median / max (ms) | "
             "encoder peak memory after 1 min / at the end (MB) | decoder peak memory after 1 min / at the end (MB) | "
             "decode frames/s | decode ms per block | "
             f"stream vs offline ({rows[0]['offline_frames'] if rows else 0} frames) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['codec']} | {r['minutes']:g} | {r['frames']:,} | {r['block_s']:g} s | {r['ratio']:.2f} | "
            f"{r['encode_fps']:,.0f} | {r['latency_median_ms']:.1f} / {r['latency_max_ms']:.1f} | "
            f"{_mb(r['rss_first_minute_mb'])} / {_mb(r['rss_end_mb'])} | "
            f"{_mb(r['rss_decoded_first_minute_mb'])} / {_mb(r['rss_decoded_mb'])} | "
            f"{r['decode_fps']:,.0f} | "
            f"{r['decode_block_ms_median']:.2f} | "
            f"{100 * (r['stream_bytes_same_frames'] / r['offline_bytes'] - 1):+.1f} % |")
    lines += ["", "Latency is the time a block takes to encode once its last frame is written (the stream's "
              "delay is the block length plus it). Memory stays flat when the end figure equals the "
              f"first-minute one ({LOADING[aot.in_use()]}). The last column is the stream of the first frames "
              "against `mocapz.compress` of the same frames (lossy codecs offline in one block).", ""]
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--codecs", default="lossless,quant")
    ap.add_argument("--offline-frames", type=int, default=4800)
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker, args.minutes, args.offline_frames)))
        return 0
    rows = []
    for codec in args.codecs.split(","):
        res = subprocess.run([sys.executable, __file__, "--worker", codec, "--minutes", str(args.minutes),
                              "--offline-frames", str(args.offline_frames)], capture_output=True, text=True,
                             env={**os.environ, **ONE_THREAD}, check=False)
        if res.returncode:
            print(res.stderr, file=sys.stderr)
            return 1
        rows.append(json.loads(res.stdout.strip().splitlines()[-1]))
    command = "python scripts/stream.py" + "".join(f" {a}" for a in sys.argv[1:])
    text = render(rows, command)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
