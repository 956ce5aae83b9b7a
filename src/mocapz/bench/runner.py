"""Running a benchmark: clips x codecs x settings, with a progress bar; failures are recorded, not fatal."""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import sys
import time
import traceback
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import Any

from mocapz import __version__
from mocapz.bench.corpus import ClipFile, default_paths, discover, quick_selection
from mocapz.bench.measure import clip_info, measure_codec, measure_generic
from mocapz.bench.sweeps import GENERIC, label, parse_codecs, settings_for
from mocapz.codecs import get_codec
from mocapz.io import load
from mocapz.model.motion import AnyMotion, Motion

#: Per codec call limit in seconds (a hung codec becomes a recorded failure).
DEFAULT_TIMEOUT = 900.0


def machine() -> dict[str, Any]:
    """Where the figures were measured: CPU, cores, OS, Python, numpy, load at the start."""
    import numpy as np

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        load1 = round(os.getloadavg()[0], 2)
    except (OSError, AttributeError):
        load1 = None
    return {"cpu": cpu, "cores": os.cpu_count(), "machine": platform.machine(), "os": platform.platform(),
            "python": platform.python_version(), "numpy": np.__version__, "load_average_at_start": load1,
            "threads": 1}


@contextmanager
def single_thread() -> Iterator[None]:
    """Limit BLAS/OpenMP pools to one thread (METRICS.md: one process, one thread)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover
        yield
        return
    with threadpool_limits(limits=1):
        yield


def _kind(motion: AnyMotion) -> str:
    return "skeleton" if isinstance(motion, Motion) else "markers"


def _applies(codec: str, motion: AnyMotion) -> bool:
    if codec in GENERIC:
        return True
    return _kind(motion) in get_codec(codec).kinds


def _error_text(exc: BaseException) -> str:
    text = f"{type(exc).__name__}: {exc}".strip()
    return text if len(text) <= 500 else text[:497] + "..."


def run_bench(paths: Sequence[Path] | None = None, codecs: Sequence[str] | None = None, quick: bool = False,
              timeout: float | None = DEFAULT_TIMEOUT, progress: bool = True, command: str | None = None,
              settings: dict[str, list[dict[str, Any]]] | None = None) -> dict[str, Any]:
    """Measure every codec at every setting of its sweep on every clip.

    Args:
        paths: motion files or folders (default: the CMU clips of the shared data folder).
        codecs: codec names (default :data:`~mocapz.bench.sweeps.DEFAULT_CODECS`); ``lossless`` is always
            measured too: it is the speed reference of every clip.
        quick: short sweeps, and from the default corpus only a handful of short clips.
        timeout: seconds allowed per codec call (``None``: no limit).
        progress: show a progress bar on stderr.
        command: the command line, for the report.
        settings: codec -> settings measured instead of its sweep (for scripts reproducing a paper's
            operating points, e.g. ``{"pga": [{"max_distortion": 0.36}]}``).

    Returns:
        The results document (what ``results.json`` holds): ``records`` has one entry per clip x codec x
        setting, each with ``status`` ``"ok"`` or ``"failed"`` (and ``error``).
    """
    names = parse_codecs(",".join(codecs) if codecs else None)
    explicit = bool(paths)
    clips = discover(list(paths) if paths else default_paths())
    if quick:
        clips = quick_selection(clips, explicit)
    started = time.time()
    doc: dict[str, Any] = {
        "mocapz_version": __version__,
        "machine": machine(),
        "command": command or "mocapz bench",
        "quick": quick,
        "codecs": names,
        "started": _dt.datetime.fromtimestamp(started, _dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "clips": [],
        "records": [],
    }
    with single_thread():
        loaded = _load_all(clips, doc)
        jobs = [(c, m, codec, s) for c, m in loaded for codec in names if _applies(codec, m)
                for s in (settings[codec] if settings and codec in settings else settings_for(codec, m, quick))]
        bar = _progress(progress)
        with bar if bar is not None else nullcontext():
            task = bar.add_task("bench", total=len(jobs)) if bar is not None else None
            for clip, motion, codec, setting in jobs:
                if bar is not None:
                    bar.update(task, description=f"{clip.clip_id} {codec} {label(setting)}"[:60])
                doc["records"].append(_one(clip, motion, codec, setting, timeout))
                if bar is not None:
                    bar.advance(task)
    _relative_speeds(doc["records"])
    doc["duration_s"] = round(time.time() - started, 1)
    return doc


def _load_all(clips: list[ClipFile], doc: dict[str, Any]) -> list[tuple[ClipFile, AnyMotion]]:
    out = []
    for c in clips:
        try:
            m = load(c.path)
            # codecs are compared on the marker stream: a C3D's other content (analogs, parameters, residuals)
            # is the same lossless sections whatever the codec, so it is left out of the comparison
            m.metadata.pop("c3d", None)
        except Exception as exc:  # noqa: BLE001 - a bad file is a recorded failure
            doc["records"].append({"clip": c.clip_id, "file": str(c.path), "codec": "(load)", "setting": {},
                                   "label": "", "status": "failed", "error": _error_text(exc)})
            continue
        info = {"clip": c.clip_id, "file": str(c.path), "raw_bytes": m.raw_bytes,
                "file_bytes": m.metadata.get("file_bytes"), **clip_info(m)}
        doc["clips"].append(info)
        out.append((c, m))
    return out


def _one(clip: ClipFile, motion: AnyMotion, codec: str, setting: dict[str, Any],
         timeout: float | None) -> dict[str, Any]:
    rec: dict[str, Any] = {"clip": clip.clip_id, "file": str(clip.path), "codec": codec, "setting": setting,
                           "label": label(setting), **clip_info(motion)}
    try:
        if codec in GENERIC:
            figs = measure_generic(motion, clip.path, codec, timeout)
        else:
            figs = measure_codec(motion, codec, setting, timeout)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - any codec failure is a result, the run goes on
        if os.environ.get("MOCAPZ_BENCH_TRACEBACK"):
            traceback.print_exc(file=sys.stderr)
        rec.update(status="failed", error=_error_text(exc))
        return rec
    figs.pop("frames", None)
    rec.update(status="ok", error=None, **figs)
    return rec


def _relative_speeds(records: list[dict[str, Any]]) -> None:
    """Add ``encode_vs_lossless`` / ``decode_vs_lossless``: time over the lossless codec's on the clip."""
    ref = {r["clip"]: r for r in records if r["codec"] == "lossless" and r.get("status") == "ok"}
    for r in records:
        base = ref.get(r["clip"])
        for k in ("encode", "decode"):
            key = f"{k}_ms_per_frame"
            ok = base is not None and r.get(key) is not None and base.get(key)
            r[f"{k}_vs_lossless"] = r[key] / base[key] if ok else None  # type: ignore[index]


def _progress(show: bool) -> Any:
    if not show:
        return None
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(TextColumn("{task.description:<60}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                    console=Console(stderr=True), transient=False)


def write_results(doc: dict[str, Any], path: Path) -> None:
    """``results.json``: sorted keys, indented, NaN/inf written as null."""
    path.write_text(json.dumps(_clean(doc), indent=1, sort_keys=True) + "\n", encoding="utf-8")


def _clean(o: Any) -> Any:
    import math

    import numpy as np

    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [_clean(v) for v in o]
    if isinstance(o, np.generic):
        o = o.item()
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, Path):
        return str(o)
    return o
