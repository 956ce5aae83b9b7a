"""Compressing a whole folder of clips: :func:`compress_folder`, the entry point of ``mocapz compress DIR``.

It ties the layers together: :func:`~mocapz.parallel.discover.plan` lists the clips and their outputs,
a :class:`~mocapz.parallel.pool.Pool` runs :func:`~mocapz.parallel.clip.compress_clip` on each (serially,
on local processes or on Dask), :class:`~mocapz.parallel.progress.BatchProgress` shows how it goes, and a
:class:`~mocapz.parallel.report.BatchReport` sums up. The output bytes do not depend on the parallelism.
"""

from __future__ import annotations

import contextlib
import functools
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mocapz.errors import MocapzError
from mocapz.format.extras_precision import ExtrasPrecision
from mocapz.parallel.clip import ClipJob, ClipResult, clip_modules, compress_clip, failure_reason
from mocapz.parallel.discover import OUTPUT_SUFFIX, plan
from mocapz.parallel.pool import Pool
from mocapz.parallel.progress import BatchProgress
from mocapz.parallel.report import BatchReport


def _largest_first(job: ClipJob) -> tuple[int, int]:
    """Submission order: largest input first, then input order."""
    try:
        size = os.path.getsize(job.source)
    except OSError:
        size = 0
    return -size, job.index


def compress_folder(input_dir: str | os.PathLike[str], output_dir: str | os.PathLike[str], codec: str = "lossless",
                    options: dict[str, Any] | None = None, *, jobs: int | None = None, scheduler: str | None = None,
                    force: bool = False, progress: bool = False, pool: Pool | None = None,
                    on_result: Callable[[ClipResult], None] | None = None,
                    block: int | float | str | None = None,
                    precision: ExtrasPrecision | None = None) -> BatchReport:
    """Compress every clip of ``input_dir`` into a ``.mcz`` under ``output_dir`` (layout mirrored).

    Args:
        codec, options: as for :func:`mocapz.compress`; the same for every clip.
        jobs: worker processes (``None``: one per CPU; ``1``: serial, in this process).
        scheduler: Dask scheduler address, or ``"local"`` for a LocalCluster on 127.0.0.1.
        force: overwrite existing outputs (otherwise such clips fail with "output exists").
        progress: show a progress bar on stderr (when it is a terminal).
        pool: an already started :class:`Pool` to run on (then ``jobs`` and ``scheduler`` are ignored and
            the pool is left open, e.g. to run several batches on one Dask cluster).
        on_result: called in this process with each :class:`ClipResult` as it completes.
        block: the length of the independent blocks every clip is coded in (:func:`mocapz.compress`).
        precision: the C3D analog channels' and tracks' precision
            (:class:`~mocapz.format.extras_precision.ExtrasPrecision`; None: exact).

    Returns:
        A :class:`BatchReport`; failed clips are in ``report.failed``, nothing is raised for them. Raises
        :class:`~mocapz.errors.MocapzError` only for problems with the whole batch (no such folder, unknown
        codec, unreachable scheduler...). The bytes written do not depend on ``jobs`` or ``scheduler``.
    """
    options = _checked(codec, options, block)
    out_root = _folder(output_dir)
    jobs_list = plan(input_dir, out_root)
    out_root.mkdir(parents=True, exist_ok=True)
    return _run(jobs_list, codec, options, jobs, scheduler, force, progress, pool, on_result, block, precision)


def compress_files(paths: list[str | os.PathLike[str]], output_dir: str | os.PathLike[str] | None,
                   codec: str = "lossless", options: dict[str, Any] | None = None, *, jobs: int | None = None,
                   scheduler: str | None = None, force: bool = False, progress: bool = False,
                   block: int | float | str | None = None, precision: ExtrasPrecision | None = None) -> BatchReport:
    """Compress the motion files ``paths`` (``mocapz compress A.bvh B.c3d ... -j N``), each into
    ``output_dir/NAME.mcz`` or, without an output folder, ``NAME.mcz`` beside it; the arguments, the report and
    the bytes as :func:`compress_folder`'s (a clip's name in the report: its path as given)."""
    options = _checked(codec, options, block)
    out_root = None if output_dir is None else _folder(output_dir)
    jobs_list = [ClipJob(i, str(path), str(Path(path).resolve()),
                         str((Path(path) if out_root is None else out_root / Path(path).name).resolve())
                         + OUTPUT_SUFFIX) for i, path in enumerate(paths)]
    if out_root is not None:
        out_root.mkdir(parents=True, exist_ok=True)
    return _run(jobs_list, codec, options, jobs, scheduler, force, progress, None, None, block, precision)


def _checked(codec: str, options: dict[str, Any] | None, block: int | float | str | None) -> dict[str, Any]:
    """The codec's options, checked, and the block length checked (a bad one: one error, not one per clip)."""
    from mocapz.blocking import block_frames
    from mocapz.codecs import get_codec

    checked = get_codec(codec).validate(options or {})
    block_frames(block, 1.0, 0.0)
    return checked


def _folder(output_dir: str | os.PathLike[str]) -> Path:
    out_root = Path(output_dir)
    if out_root.exists() and not out_root.is_dir():
        raise MocapzError(f"{out_root}: output exists and is not a folder")
    return out_root


def _run(jobs_list: list[ClipJob], codec: str, options: dict[str, Any], jobs: int | None, scheduler: str | None,
         force: bool, progress: bool, pool: Pool | None, on_result: Callable[[ClipResult], None] | None,
         block: int | float | str | None, precision: ExtrasPrecision | None) -> BatchReport:
    """Run :func:`~mocapz.parallel.clip.compress_clip` on every job with checked ``options`` (see
    :func:`compress_folder`)."""
    worker = functools.partial(compress_clip, codec=codec, options=options, force=force, block=block,
                               precision=precision)
    results: list[ClipResult | None] = [None] * len(jobs_list)
    t0 = time.perf_counter()
    own = pool is None
    run_on = Pool(jobs, scheduler, max_items=len(jobs_list), preload=clip_modules(codec)) if pool is None else pool
    with run_on if own else contextlib.nullcontext(run_on) as active, \
            BatchProgress(len(jobs_list), f"{codec}, {active.short_description}", enabled=progress) as bar:
        t_ready = time.perf_counter()
        # Largest inputs first, so no long clip is left running alone at the end; results are stored by
        # index, so the order of submission changes nothing in the outputs or the report.
        submit = jobs_list if active.mode == "serial" else sorted(jobs_list, key=_largest_first)
        for outcome in active.imap(worker, submit):
            job: ClipJob = outcome.item
            if outcome.error is not None:
                res = ClipResult(job.index, job.name, None, error=failure_reason(outcome.error, job.source),
                                 error_type=type(outcome.error).__name__)
            else:
                res = outcome.value
            results[job.index] = res
            bar.update(res)
            if on_result is not None:
                on_result(res)
        t_done = time.perf_counter()
    seconds = time.perf_counter() - t0
    return BatchReport([r for r in results if r is not None], seconds, active.startup_seconds if own else 0.0,
                       active.mode, active.workers, active.description, codec, work_seconds=t_done - t_ready)
