"""One clip as a unit of work: the job (:class:`ClipJob`), the worker functions that run it in a worker process
(:func:`compress_clip`, :func:`load_motion`), and the small record sent back (:class:`ClipResult`).

The worker functions are picklable module-level functions and never raise for a bad clip: each clip is
coded on its own, by the same function, whatever runs it, so the output bytes do not depend on the
parallelism. :func:`clip_modules` lists the modules such a worker imports, for the pools to preload.
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mocapz.errors import FormatError, MocapzError
from mocapz.model.motion import AnyMotion

if TYPE_CHECKING:
    from mocapz.format.extras_precision import ExtrasPrecision


@dataclass(frozen=True)
class ClipJob:
    """One clip to compress.

    Attributes:
        index: position in the sorted input list (results are reported in this order).
        name: path relative to the input folder, with ``/`` separators (the clip's name in reports).
        source: absolute input path.
        output: absolute output path.
    """

    index: int
    name: str
    source: str
    output: str


@dataclass(frozen=True)
class ClipResult:
    """What one clip's worker sends back (small: no motion data).

    Attributes:
        index: the job's index.
        name: the clip's relative input path.
        output: the output path (``None`` if nothing was written).
        frames: frames read (0 on failure).
        raw_bytes: METRICS.md raw size (float32 channel data) of the clip.
        input_bytes: size of the input file.
        bytes: size of the ``.mcz`` written.
        seconds: wall time of load + compress + write in the worker.
        cpu_seconds: CPU time the worker spent on it (``seconds`` minus waiting for a CPU or the disk).
        error: why the clip failed (without the file name), or ``None``.
        error_type: the exception class name of a failure.
    """

    index: int
    name: str
    output: str | None
    frames: int = 0
    raw_bytes: int = 0
    input_bytes: int = 0
    bytes: int = 0
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    error: str | None = None
    error_type: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


def failure_reason(exc: BaseException, path: str | os.PathLike[str]) -> str:
    """An exception's message without the file name it may start with (reports add it once)."""
    path = str(path)
    if isinstance(exc, FormatError):
        return exc.problem if exc.line is None else f"line {exc.line}: {exc.problem}"
    text = str(exc) or type(exc).__name__
    for prefix in (f"{path}: ", f"{path}:"):
        if text.startswith(prefix):
            return text[len(prefix):]
    if isinstance(exc, MocapzError):
        return text
    return f"{type(exc).__name__}: {text}"


def compress_clip(job: ClipJob, codec: str = "lossless", options: dict[str, Any] | None = None,
                  force: bool = False, block: int | float | str | None = None,
                  precision: ExtrasPrecision | None = None) -> ClipResult:
    """Load one clip, compress it and write its ``.mcz`` atomically; never raises for a bad clip.

    Any error (unreadable file, codec refusing the data, existing output without ``force``...) is
    caught and returned in :attr:`ClipResult.error`, so one bad clip never stops a batch. ``options`` are
    checked ones (``CodecInfo.validate``, done once by :func:`~mocapz.parallel.folder.compress_folder`);
    ``block`` the block length and ``precision`` the C3D analogs' and tracks' (:func:`mocapz.compress`).
    """
    from mocapz.api import compress_checked
    from mocapz.codecs import get_codec
    from mocapz.io import load
    from mocapz.io.common import atomic_write

    t0 = time.perf_counter()
    c0 = time.process_time()
    try:
        out = Path(job.output)
        if out.exists() and not force:
            raise MocapzError(f"output {out} exists (use -f / force=True to overwrite)")
        in_bytes = os.path.getsize(job.source) if os.path.exists(job.source) else 0
        motion = load(job.source)
        data = compress_checked(motion, get_codec(codec), options or {}, block, precision=precision)
        out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(out, lambda tmp: tmp.write_bytes(data), force=force)
        return ClipResult(job.index, job.name, job.output, motion.n_frames, motion.raw_bytes, in_bytes, len(data),
                          time.perf_counter() - t0, time.process_time() - c0)
    except MemoryError:
        return ClipResult(job.index, job.name, None, seconds=time.perf_counter() - t0, error="out of memory",
                          error_type="MemoryError")
    except Exception as exc:  # noqa: BLE001 - a bad clip is reported, never fatal to the batch
        return ClipResult(job.index, job.name, None, seconds=time.perf_counter() - t0,
                          error=failure_reason(exc, job.source), error_type=type(exc).__name__)


def load_motion(path: str | os.PathLike[str]) -> AnyMotion:
    """:func:`mocapz.io.load` as a picklable worker function (ASF beside an AMC found as usual)."""
    from mocapz.io import load

    return load(path)


def clip_modules(codec: str) -> list[str]:
    """Modules a :func:`compress_clip` or :func:`load_motion` worker needs: readers, container, the codec's
    encoder, and the worker side of the pools (:mod:`mocapz.parallel.worker`, this module)."""
    mods = ["numpy", "mocapz.api", "mocapz.io", "mocapz.io.bvh", "mocapz.io.asf", "mocapz.io.amc", "mocapz.io.c3d",
            "mocapz.io.trc", "mocapz.parallel.worker", "mocapz.parallel.clip"]
    with contextlib.suppress(Exception):
        from mocapz.codecs import get_codec

        mods.append(get_codec(codec).encode.__module__)
    return mods
