"""Measuring one codec at one setting on one clip: encode, decode, score (METRICS.md figures), time."""

from __future__ import annotations

import bz2
import gzip
import lzma
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import zstandard

from mocapz.api import compress, decompress
from mocapz.errors import MocapzError
from mocapz.metrics.figures import evaluate, size_figures
from mocapz.model.motion import AnyMotion, Motion

T = TypeVar("T")

#: Repeat a codec call whose first run took less than this (seconds) and keep the fastest run.
REPEAT_BELOW_S = 0.05
REPEATS = 3


class BenchTimeout(MocapzError):
    """A codec call ran longer than the benchmark's per-call limit."""


@contextmanager
def time_limit(seconds: float | None) -> Iterator[None]:
    """Raise :class:`BenchTimeout` in the calling code after ``seconds`` (main thread on Unix only)."""
    usable = (seconds is not None and seconds > 0 and hasattr(signal, "setitimer")
              and threading.current_thread() is threading.main_thread())
    if not usable:
        yield
        return

    def _raise(signum: int, frame: Any) -> None:
        raise BenchTimeout(f"timed out after {seconds:g} s")

    old = signal.signal(signal.SIGALRM, _raise)
    signal.setitimer(signal.ITIMER_REAL, float(seconds))  # type: ignore[arg-type]
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def timed(fn: Callable[[], T]) -> tuple[T, float, bool | None]:
    """Run ``fn``; if it is fast, run it again (``REPEATS`` runs in all) and keep the fastest wall time.

    Returns the first result, the wall time in seconds, and for bytes results run more than once whether
    every run gave the same bytes (a determinism check), else ``None``.
    """
    t0 = time.perf_counter()
    first = fn()
    best = time.perf_counter() - t0
    same: bool | None = None
    if best < REPEAT_BELOW_S:
        for _ in range(REPEATS - 1):
            t0 = time.perf_counter()
            again = fn()
            best = min(best, time.perf_counter() - t0)
            if isinstance(first, bytes | bytearray):
                same = (same is not False) and again == first
    return first, best, same


def clip_info(motion: AnyMotion) -> dict[str, Any]:
    """Clip fields of a record: format, kind, frames, rate, duration, columns, unit."""
    d: dict[str, Any] = {"format": motion.source_format, "frames": motion.n_frames,
                         "frame_rate": motion.frame_rate, "duration_s": motion.duration}
    if isinstance(motion, Motion):
        d.update(kind="skeleton", joints=motion.skeleton.n_joints, channels=motion.skeleton.n_channels,
                 unit_cm=motion.skeleton.unit_cm)
    else:
        d.update(kind="markers", markers=motion.n_markers, unit_cm=motion.unit_cm,
                 missing_pct=100.0 * float(motion.missing.mean()) if motion.positions.size else 0.0)
    return d


def measure_codec(motion: AnyMotion, codec: str, setting: dict[str, Any],
                  timeout: float | None = None) -> dict[str, Any]:
    """Compress with ``codec`` at ``setting``, decompress, score.

    Returns the size figures (``compressed_bytes`` is the whole ``.mcz`` file), every error figure of
    :func:`mocapz.metrics.figures.evaluate` (with ``*_cm``), and ``encode_ms_per_frame`` / ``decode_ms_per_frame``:
    wall time of :func:`mocapz.compress` / :func:`mocapz.decompress` alone (no parsing, no writing),
    fastest of up to 3 runs for calls under 50 ms; ``deterministic``: whether repeated encodes gave the
    same bytes (``None`` when the encode ran once). Errors propagate to the caller.
    """
    frames = max(motion.n_frames, 1)
    with time_limit(timeout):
        data, t_enc, same = timed(lambda: compress(motion, codec=codec, **setting))
        decoded, t_dec, _ = timed(lambda: decompress(data))
    out: dict[str, Any] = dict(size_figures(motion, len(data)))
    out.update(evaluate(motion, decoded).as_dict())
    out.update(encode_ms_per_frame=1000.0 * t_enc / frames, decode_ms_per_frame=1000.0 * t_dec / frames,
               deterministic=same)
    return out


# ---------------------------------------------------------------- general-purpose compressors
def _zstd_c(b: bytes) -> bytes:
    return zstandard.ZstdCompressor(level=19).compress(b)


def _zstd_d(b: bytes) -> bytes:
    return zstandard.ZstdDecompressor().decompress(b)


#: name -> (compress, decompress, description); fixed levels, no timestamps (deterministic bytes).
COMPRESSORS: dict[str, tuple[Callable[[bytes], bytes], Callable[[bytes], bytes], str]] = {
    "gzip": (lambda b: gzip.compress(b, compresslevel=9, mtime=0), gzip.decompress, "gzip -9"),
    "bzip2": (lambda b: bz2.compress(b, 9), bz2.decompress, "bzip2 -9"),
    "xz": (lambda b: lzma.compress(b, preset=9), lzma.decompress, "xz -9"),
    "zstd": (_zstd_c, _zstd_d, "zstd -19"),
}


def source_files(motion: AnyMotion, path: Path) -> list[Path]:
    """The files a user keeps for this clip: the motion file, plus the ``.asf`` of an ``.amc``."""
    files = [Path(path)]
    asf = motion.metadata.get("asf_path")
    if asf:
        files.insert(0, Path(asf))
    return files


def measure_generic(motion: AnyMotion, path: Path, name: str, timeout: float | None = None) -> dict[str, Any]:
    """A general-purpose compressor on the clip's source file bytes (ASF + AMC concatenated).

    Lossless: every error figure is 0. ``ratio`` = raw_bytes / compressed size, ``ratio_file`` = source
    bytes / compressed size; times are the compressor / decompressor calls alone.
    """
    comp, decomp, _ = COMPRESSORS[name]
    src = b"".join(p.read_bytes() for p in source_files(motion, path))
    frames = max(motion.n_frames, 1)
    with time_limit(timeout):
        packed, t_enc, same = timed(lambda: comp(src))
        back, t_dec, _ = timed(lambda: decomp(packed))
    if back != src:
        raise MocapzError(f"{name} did not give the source bytes back")
    out: dict[str, Any] = dict(size_figures(motion, len(packed), source_bytes=len(src)))
    unit_cm = motion.skeleton.unit_cm if isinstance(motion, Motion) else motion.unit_cm
    zero_cm = 0.0 if unit_cm else None
    out.update(distortion_pct=0.0, arms=0.0, max_err=0.0, p99_err=0.0, bone_len_err=0.0, foot_skate=0.0,
               foot_skate_window=0.0, jitter_pct=0.0,
               unit_cm=unit_cm, arms_cm=zero_cm, max_err_cm=zero_cm, p99_err_cm=zero_cm,
               foot_skate_cm_per_s=zero_cm, foot_skate_window_cm_per_s=zero_cm,
               encode_ms_per_frame=1000.0 * t_enc / frames,
               decode_ms_per_frame=1000.0 * t_dec / frames, deterministic=same, source_bytes=len(src))
    return out
