"""Batch compression of a folder of clips: serially, on a local process pool, or on a Dask cluster.

The engine has three layers, each usable on its own:

* :func:`discover` and :func:`plan` list the motion files of a folder (``.bvh``, ``.amc``, ``.c3d``,
  ``.trc``; recursive; sorted; hidden files skipped) and map each to a ``.mcz`` path in the output folder
  that mirrors the input layout.
* :class:`Pool` runs a picklable function over a stream of items in this process (``jobs=1``), on a
  :class:`concurrent.futures.ProcessPoolExecutor` (``jobs=N``) or on a ``dask.distributed`` cluster
  (``scheduler=ADDRESS``, or ``"local"`` for a :class:`~distributed.LocalCluster` on 127.0.0.1). At
  most ``window`` items are in flight at once, so memory stays bounded however long the stream is, and
  each outcome carries the item's index, so callers can put results back in input order.
* :func:`compress_clip` is the per-clip worker (load, compress, atomic write; errors caught and returned
  in a small :class:`ClipResult`), and :func:`compress_folder` ties everything together, with an optional
  rich progress bar showing clips/s and frames/s.

Determinism: each clip is coded on its own, by the same function, with BLAS limited to one thread in
every mode (serial included), so the output bytes do not depend on ``jobs`` or on the scheduler.

On a real Dask cluster the workers must have the same mocapz installed and see the input and output
folders at the same paths (a shared file system): workers read the clips and write the ``.mcz`` files
themselves; only file names and small result records travel through the scheduler.
"""

from __future__ import annotations

import contextlib
import functools
import multiprocessing
import os
import pickle
import shutil
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from mocapz.errors import FormatError, MocapzError, OptionError
from mocapz.model.motion import AnyMotion

BATCH_EXTENSIONS = (".bvh", ".amc", ".c3d", ".trc")
OUTPUT_SUFFIX = ".mcz"


class WorkerCrashed(MocapzError):
    """A worker process died while running an item (crash in native code, or killed for memory)."""


class WorkerError(MocapzError):
    """An exception raised in a worker that could not be sent back as itself (not picklable)."""


# ------------------------------------------------------------------ inputs and outputs
def discover(input_dir: str | os.PathLike[str]) -> list[Path]:
    """Motion files under ``input_dir``, recursively, in a deterministic order.

    Files with a :data:`BATCH_EXTENSIONS` suffix (any case) are listed; names starting with ``.`` (hidden
    files and folders, temporary files) are skipped; symbolic links to folders are not followed. The order
    is that of the relative path components, so it does not depend on the file system.
    """
    root = Path(input_dir)
    if not root.exists():
        raise FormatError(root, "no such folder")
    if not root.is_dir():
        raise MocapzError(f"{root}: not a folder")
    errors: list[OSError] = []
    found: list[Path] = []
    for dirpath, dirnames, filenames in os.walk(root, onerror=errors.append):
        dirnames[:] = [d for d in dirnames if not d.startswith(".")]
        for name in filenames:
            if not name.startswith(".") and os.path.splitext(name)[1].lower() in BATCH_EXTENSIONS:
                found.append(Path(dirpath) / name)
    if errors:
        exc = errors[0]
        raise MocapzError(f"{exc.filename or root}: cannot list folder ({exc.strerror or exc})")
    return sorted(found, key=lambda p: p.relative_to(root).parts)


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


def plan(input_dir: str | os.PathLike[str], output_dir: str | os.PathLike[str]) -> list[ClipJob]:
    """The clips of ``input_dir`` (see :func:`discover`) and the ``.mcz`` file each is written to.

    ``a/b/walk.bvh`` goes to ``OUTDIR/a/b/walk.mcz``. When two inputs of one folder share a stem
    (``walk.bvh`` and ``walk.c3d``), both keep their extension instead (``walk.bvh.mcz``, ``walk.c3d.mcz``),
    so no output is written twice; the rule depends only on the file names, so it is deterministic.
    """
    root = Path(input_dir).resolve()
    out_root = Path(output_dir).resolve()
    rels = [p.relative_to(root) for p in discover(root)]
    stems: dict[Path, int] = {}
    for rel in rels:
        key = rel.with_suffix(OUTPUT_SUFFIX)
        stems[key] = stems.get(key, 0) + 1
    jobs: list[ClipJob] = []
    seen: set[Path] = set()
    for i, rel in enumerate(rels):
        out = rel.with_suffix(OUTPUT_SUFFIX)
        if stems[out] > 1:
            out = rel.parent / (rel.name + OUTPUT_SUFFIX)
        if out in seen:
            raise MocapzError(f"{root / rel}: two inputs map to the same output {out_root / out}")
        seen.add(out)
        jobs.append(ClipJob(i, rel.as_posix(), str(root / rel), str(out_root / out)))
    return jobs


# ------------------------------------------------------------------ the per-clip worker
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
                  force: bool = False) -> ClipResult:
    """Load one clip, compress it and write its ``.mcz`` atomically; never raises for a bad clip.

    Any error (unreadable file, codec refusing the data, existing output without ``force``...) is
    caught and returned in :attr:`ClipResult.error`, so one bad clip never stops a batch.
    """
    from mocapz.api import compress
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
        data = compress(motion, codec=codec, **(options or {}))
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


# ------------------------------------------------------------------ where work runs
@dataclass(frozen=True)
class Outcome:
    """The result of one item run by :meth:`Pool.imap`: ``value`` or the ``error`` it raised."""

    index: int
    item: Any
    value: Any = None
    error: BaseException | None = None


_BLAS_LIMITED = False


def _limit_blas_once() -> None:
    """Limit BLAS/OpenMP to one thread in this (worker) process, once: same numerics in every mode."""
    global _BLAS_LIMITED
    if _BLAS_LIMITED:
        return
    _BLAS_LIMITED = True
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl comes with scikit-learn
        return
    threadpool_limits(limits=1)


@dataclass(frozen=True)
class _Raised:
    """An exception raised by the function in a worker, in a form that always survives pickling."""

    exc: BaseException | None
    type_name: str
    message: str
    format_error: tuple[str | None, str, int | None] | None = None

    @classmethod
    def of(cls, exc: BaseException) -> _Raised:
        try:
            pickle.loads(pickle.dumps(exc))
            return cls(exc, type(exc).__name__, str(exc))
        except Exception:  # noqa: BLE001 - e.g. an exception class whose __init__ takes other arguments
            fmt = (exc.path, exc.problem, exc.line) if isinstance(exc, FormatError) else None
            return cls(None, type(exc).__name__, str(exc), fmt)

    def rebuild(self) -> BaseException:
        if self.exc is not None:
            return self.exc
        if self.format_error is not None:
            return FormatError(*self.format_error)
        return WorkerError(f"{self.type_name}: {self.message}")


def _call_in_worker(fn: Callable[[Any], Any], item: Any) -> Any:
    _limit_blas_once()
    try:
        return fn(item)
    except Exception as exc:  # noqa: BLE001 - sent back, turned into Outcome.error
        return _Raised.of(exc)


def _outcome(i: int, item: Any, value: Any) -> Outcome:
    return Outcome(i, item, error=value.rebuild()) if isinstance(value, _Raised) else Outcome(i, item, value)


def _one_blas_thread() -> contextlib.AbstractContextManager[Any]:
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover
        return contextlib.nullcontext()
    return threadpool_limits(limits=1)


def available_cpus() -> int:
    """CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _mp_context(preload: Sequence[str] = ()) -> multiprocessing.context.BaseContext:
    # forkserver: workers start from a clean process (no threads copied from the parent, e.g. the
    # progress bar's), and the server imports `preload` once, so every worker forks from it warm (and
    # shares those pages); spawn where forkserver does not exist.
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        if preload:
            ctx.set_forkserver_preload(list(preload))  # ignored if this process's forkserver already runs
        return ctx
    return multiprocessing.get_context("spawn")


def _import_modules(modules: Sequence[str]) -> None:
    """Import modules in a worker (warm-up before the first item); unknown ones are skipped."""
    import importlib

    for name in modules:
        with contextlib.suppress(ImportError):
            importlib.import_module(name)


def clip_modules(codec: str) -> list[str]:
    """Modules a :func:`compress_clip` worker needs: readers, container and the codec's encoder."""
    mods = ["numpy", "mocapz.api", "mocapz.io", "mocapz.io.bvh", "mocapz.io.amc", "mocapz.io.c3d",
            "mocapz.io.trc", "mocapz.parallel.batch"]
    with contextlib.suppress(Exception):
        from mocapz.codecs import get_codec

        mods.append(get_codec(codec).encode.__module__)
    return mods


class Pool:
    """Runs a function over items: in this process, on a local process pool, or on a Dask cluster.

    Args:
        jobs: worker processes for the local pool (``None``: one per available CPU; ``1``: no pool,
            run in this process). With ``scheduler="local"`` it is the number of Dask workers.
        scheduler: ``None`` for a local pool, ``"local"`` to start a Dask LocalCluster on 127.0.0.1, or
            a Dask scheduler address (``tcp://host:8786``). Needs ``pip install 'mocapz[dask]'``.
        max_items: upper bound on the number of items, to start no more workers than needed.
        preload: modules every worker imports before its first item (e.g. :func:`clip_modules`), so the
            first items do not pay for imports; with a local pool the forkserver imports them once.

    Use as a context manager (``with Pool(jobs=2) as pool: for o in pool.imap(fn, items): ...``); the
    pool or cluster is started on entry and shut down on exit.
    """

    def __init__(self, jobs: int | None = None, scheduler: str | None = None, max_items: int | None = None,
                 preload: Sequence[str] = ()) -> None:
        if jobs is not None and jobs < 1:
            raise OptionError(f"--jobs must be at least 1, got {jobs}")
        self.scheduler = scheduler
        self.jobs = jobs
        want = jobs if jobs is not None else available_cpus()
        if max_items is not None and scheduler is None:
            want = max(1, min(want, max_items))
        self.workers = want
        self.mode = "dask" if scheduler else ("serial" if want == 1 else "processes")
        self.startup_seconds = 0.0
        self.preload = tuple(preload)
        self._executor: ProcessPoolExecutor | None = None
        self._client: Any = None
        self._cluster: Any = None
        self._scratch: str | None = None

    # -- lifecycle
    def __enter__(self) -> Pool:
        t0 = time.perf_counter()
        if self.mode == "processes":
            self._executor = self._new_executor(self.workers)
            # Start every worker now (one warm-up task each: the pool starts a process per task while
            # none is idle), so start-up is measured here and the first items do not wait for it.
            wait([self._executor.submit(_import_modules, self.preload) for _ in range(self.workers)])
        elif self.mode == "dask":
            self._start_dask()
        self.startup_seconds = time.perf_counter() - t0
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None
        if self._client is not None:
            with contextlib.suppress(Exception):
                self._client.close()
            self._client = None
        if self._cluster is not None:
            with contextlib.suppress(Exception):
                self._cluster.close()
            self._cluster = None
        if self._scratch is not None:
            shutil.rmtree(self._scratch, ignore_errors=True)
            self._scratch = None

    @property
    def description(self) -> str:
        if self.mode == "serial":
            return "serial"
        if self.mode == "processes":
            return f"{self.workers} processes"
        where = "LocalCluster 127.0.0.1" if self.scheduler == "local" else str(self.scheduler)
        return f"dask {where}, {self.workers} worker threads"

    @property
    def short_description(self) -> str:
        return {"serial": "serial", "processes": f"{self.workers} processes"}.get(self.mode, f"dask x{self.workers}")

    def _new_executor(self, workers: int) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=workers, mp_context=_mp_context(self.preload))

    def _start_dask(self) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise OptionError("--scheduler needs Dask: pip install 'mocapz[dask]' "
                              "(or pip install 'dask[distributed]')") from None
        import logging

        if self.scheduler == "local":
            n = self.jobs if self.jobs is not None else available_cpus()
            self._scratch = tempfile.mkdtemp(prefix="mocapz-dask-")  # workers' scratch space, removed on close
            import dask

            with dask.config.set({"temporary-directory": self._scratch}):
                self._cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                                             dashboard_address=None, silence_logs=logging.CRITICAL,
                                             local_directory=self._scratch)
            self._client = Client(self._cluster)
            self._client.wait_for_workers(n)
        else:
            try:
                self._client = Client(self.scheduler, timeout="20s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise MocapzError(f"cannot reach Dask scheduler {self.scheduler}: {exc}") from None
        if self.preload:
            self._client.run(_import_modules, list(self.preload))
        threads = sum(self._client.nthreads().values())
        self.workers = max(1, threads)

    # -- running
    def imap(self, fn: Callable[[Any], Any], items: Iterable[Any], window: int | None = None,
             ordered: bool = False) -> Iterator[Outcome]:
        """Run ``fn(item)`` for every item; yield an :class:`Outcome` per item.

        ``fn`` must be picklable (a module-level function or a :func:`functools.partial` of one) and should
        return small values. ``items`` is consumed lazily: at most ``window`` items (default: twice the
        workers) are submitted and not yet yielded at any time, so a long stream never piles up in memory.
        Outcomes come in completion order, or in input order with ``ordered=True``. An exception raised
        by ``fn`` is returned in :attr:`Outcome.error`; a worker process that dies is reported as
        :class:`WorkerCrashed` for the item(s) it was running and the pool carries on.
        """
        window = max(1, window if window is not None else 2 * self.workers)
        stream = enumerate(items)
        # In input order, early finishers wait in `pending` until their turn; they count against the
        # window, so submitted-but-not-yielded items never exceed it.
        pending: dict[int, Outcome] = {}
        held: Callable[[], int] = (lambda: len(pending)) if ordered else (lambda: 0)
        if self.mode == "serial":
            raw = self._imap_serial(fn, stream)
        elif self.mode == "processes":
            raw = self._imap_processes(fn, stream, window, held)
        else:
            raw = self._imap_dask(fn, stream, window, held)
        if not ordered:
            yield from raw
            return
        nxt = 0
        for outcome in raw:
            pending[outcome.index] = outcome
            while nxt in pending:
                yield pending.pop(nxt)
                nxt += 1

    def _imap_serial(self, fn: Callable[[Any], Any], stream: Iterator[tuple[int, Any]]) -> Iterator[Outcome]:
        with _one_blas_thread():
            for i, item in stream:
                try:
                    value = fn(item)
                except Exception as exc:  # noqa: BLE001 - reported per item
                    yield Outcome(i, item, error=exc)
                else:
                    yield Outcome(i, item, value)

    def _imap_processes(self, fn: Callable[[Any], Any], stream: Iterator[tuple[int, Any]], window: int,
                        held: Callable[[], int]) -> Iterator[Outcome]:
        call = functools.partial(_call_in_worker, fn)
        running: dict[Future[Any], tuple[int, Any]] = {}
        exhausted = False
        while True:
            while not exhausted and len(running) + held() < window:
                nxt = next(stream, None)
                if nxt is None:
                    exhausted = True
                    break
                assert self._executor is not None
                running[self._executor.submit(call, nxt[1])] = nxt
            if not running:
                return
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            if not any(isinstance(f.exception(), BrokenProcessPool) for f in done):
                for fut in sorted(done, key=lambda f: running[f][0]):
                    i, item = running.pop(fut)
                    exc = fut.exception()
                    yield Outcome(i, item, error=exc) if exc is not None else _outcome(i, item, fut.result())
                continue
            # A worker died and took every item still in the pool with it. Keep what had finished, start a
            # new pool, and rerun each lost item alone, so the one that kills its worker again is reported.
            lost: list[tuple[int, Any]] = []
            finished: list[Outcome] = []
            for fut, (i, item) in sorted(running.items(), key=lambda kv: kv[1][0]):
                exc = fut.exception() if fut.done() else BrokenProcessPool()
                if isinstance(exc, BrokenProcessPool):
                    lost.append((i, item))
                else:
                    finished.append(Outcome(i, item, error=exc) if exc is not None else _outcome(i, item, fut.result()))
            running.clear()
            assert self._executor is not None
            self._executor.shutdown(wait=False, cancel_futures=True)
            self._executor = self._new_executor(self.workers)
            yield from finished
            for i, item in lost:
                yield self._run_alone(call, i, item)

    def _run_alone(self, call: Callable[[Any], Any], i: int, item: Any) -> Outcome:
        with self._new_executor(1) as solo:
            try:
                return _outcome(i, item, solo.submit(call, item).result())
            except BrokenProcessPool:
                return Outcome(i, item, error=WorkerCrashed("the worker process died while running it "
                                                            "(crash in native code, or out of memory)"))
            except Exception as exc:  # noqa: BLE001 - reported per item
                return Outcome(i, item, error=exc)

    def _imap_dask(self, fn: Callable[[Any], Any], stream: Iterator[tuple[int, Any]], window: int,
                   held: Callable[[], int]) -> Iterator[Outcome]:
        from distributed import as_completed

        try:
            from distributed.scheduler import KilledWorker
        except ImportError:  # pragma: no cover - older layouts
            from distributed import KilledWorker  # type: ignore[no-redef,attr-defined]

        client = self._client
        call = functools.partial(_call_in_worker, fn)
        tag = f"mocapz-{os.getpid()}-{time.time_ns()}"
        meta: dict[str, tuple[int, Any]] = {}
        ac = as_completed()
        exhausted = False

        def refill() -> None:
            nonlocal exhausted
            while not exhausted and len(meta) + held() < window:
                nxt = next(stream, None)
                if nxt is None:
                    exhausted = True
                    return
                fut = client.submit(call, nxt[1], key=f"{tag}-{nxt[0]}", pure=False, retries=0)
                meta[fut.key] = nxt
                ac.add(fut)

        refill()
        for fut in ac:
            i, item = meta.pop(fut.key)
            try:
                outcome = _outcome(i, item, fut.result())
            except KilledWorker:
                outcome = Outcome(i, item, error=WorkerCrashed("Dask workers died while running it "
                                                               "(crash in native code, or out of memory)"))
            except Exception as exc:  # noqa: BLE001 - reported per item
                outcome = Outcome(i, item, error=exc)
            fut.release()
            yield outcome
            refill()


def load_motion(path: str | os.PathLike[str]) -> AnyMotion:
    """:func:`mocapz.io.load` as a picklable worker function (ASF beside an AMC found as usual)."""
    from mocapz.io import load

    return load(path)


def load_many(paths: Iterable[str | os.PathLike[str]], *, jobs: int | None = None, scheduler: str | None = None,
              pool: Pool | None = None) -> Iterator[tuple[Path, AnyMotion | None, str | None]]:
    """Read motion files in parallel; yield ``(path, motion, None)`` or ``(path, None, reason)`` in input order.

    For commands that need the clips themselves (e.g. ``compress-db``, whose shared pattern databases need
    every clip): parsing is spread over the workers and the motions come back to this process, in order,
    with at most ``2 x workers`` of them waiting at once beyond those already consumed.
    """
    items = [Path(p) for p in paths]
    own = pool is None
    run_on = Pool(jobs, scheduler, max_items=len(items), preload=clip_modules("lossless")) if own else pool
    with run_on if own else contextlib.nullcontext(run_on) as active:
        for o in active.imap(load_motion, [str(p.resolve()) for p in items], ordered=True):
            path = items[o.index]
            if o.error is not None:
                yield path, None, failure_reason(o.error, o.item)
            else:
                yield path, o.value, None


# ------------------------------------------------------------------ the whole batch
@dataclass
class BatchReport:
    """Results of a batch, in input order, with totals.

    ``seconds`` is the wall time of the whole batch as a user sees it (listing, pool or cluster start,
    work, shutdown); ``startup_seconds`` the pool or cluster start alone; ``work_seconds`` the time from
    the pool being ready to the last result. Rates are per ``seconds``.
    """

    results: list[ClipResult]
    seconds: float
    startup_seconds: float
    mode: str
    workers: int
    description: str
    codec: str = "lossless"
    work_seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def failed(self) -> list[ClipResult]:
        return [r for r in self.results if not r.ok]

    @property
    def frames(self) -> int:
        return sum(r.frames for r in self.results if r.ok)

    @property
    def raw_bytes(self) -> int:
        return sum(r.raw_bytes for r in self.results if r.ok)

    @property
    def input_bytes(self) -> int:
        return sum(r.input_bytes for r in self.results if r.ok)

    @property
    def compressed_bytes(self) -> int:
        return sum(r.bytes for r in self.results if r.ok)

    @property
    def cpu_seconds(self) -> float:
        """CPU time spent in the workers on the clips (all clips, failed ones included)."""
        return sum(r.cpu_seconds for r in self.results)

    @property
    def frames_per_second(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    @property
    def clips_per_second(self) -> float:
        return len(self.results) / self.seconds if self.seconds > 0 else 0.0

    def as_dict(self, with_results: bool = True) -> dict[str, Any]:
        comp = self.compressed_bytes
        d: dict[str, Any] = {
            "codec": self.codec, "mode": self.mode, "workers": self.workers, "parallelism": self.description,
            "clips": len(self.results), "ok": len(self.results) - len(self.failed), "failed": len(self.failed),
            "frames": self.frames, "raw_bytes": self.raw_bytes, "input_bytes": self.input_bytes,
            "compressed_bytes": comp, "ratio": self.raw_bytes / comp if comp else None,
            "ratio_file": self.input_bytes / comp if comp else None,
            "seconds": self.seconds, "startup_seconds": self.startup_seconds, "work_seconds": self.work_seconds,
            "cpu_seconds": self.cpu_seconds,
            "frames_per_second": self.frames_per_second, "clips_per_second": self.clips_per_second,
            "failures": [{"name": r.name, "error": r.error, "error_type": r.error_type} for r in self.failed],
        }
        d.update(self.extra)
        if with_results:
            d["results"] = [asdict(r) for r in self.results]
        return d


class BatchProgress:
    """A rich progress bar on stderr: clips done / total, clips/s, frames/s, failures, ETA.

    Disabled (a no-op) when ``enabled`` is false or stderr is not a terminal.
    """

    def __init__(self, total: int, description: str = "compressing", enabled: bool = True) -> None:
        self.total = total
        self.frames = 0
        self.failed = 0
        self._progress: Any = None
        self._task: Any = None
        if not enabled:
            return
        from rich.console import Console

        console = Console(stderr=True)
        if not console.is_terminal:
            return
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            ProgressColumn,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )
        from rich.text import Text

        class _Rates(ProgressColumn):
            """Clips per second and frames per second since the start."""

            def render(self, task: Any) -> Text:
                el = task.elapsed or 0.0
                if el <= 0:
                    return Text("- clips/s, - frames/s", style="progress.data.speed")
                frames = task.fields.get("frames", 0)
                return Text(f"{task.completed / el:,.1f} clips/s, {frames / el:,.0f} frames/s",
                            style="progress.data.speed")

        self._progress = Progress(TextColumn("[progress.description]{task.description}"), BarColumn(bar_width=24),
                                  MofNCompleteColumn(), _Rates(), TextColumn("{task.fields[failed_text]}", style="red"),
                                  TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(), console=console,
                                  transient=False)
        self._task = self._progress.add_task(description, total=total, frames=0, failed_text="")

    def __enter__(self) -> BatchProgress:
        if self._progress is not None:
            self._progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()

    def update(self, result: ClipResult) -> None:
        self.frames += result.frames
        self.failed += 0 if result.ok else 1
        if self._progress is not None:
            self._progress.update(self._task, advance=1, frames=self.frames,
                                  failed_text=f"{self.failed} failed" if self.failed else "")


def _largest_first(job: ClipJob) -> tuple[int, int]:
    try:
        size = os.path.getsize(job.source)
    except OSError:
        size = 0
    return -size, job.index


def compress_folder(input_dir: str | os.PathLike[str], output_dir: str | os.PathLike[str], codec: str = "lossless",
                    options: dict[str, Any] | None = None, *, jobs: int | None = None, scheduler: str | None = None,
                    force: bool = False, progress: bool = False, pool: Pool | None = None,
                    on_result: Callable[[ClipResult], None] | None = None) -> BatchReport:
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

    Returns:
        A :class:`BatchReport`; failed clips are in ``report.failed``, nothing is raised for them. Raises
        :class:`~mocapz.errors.MocapzError` only for problems with the whole batch (no such folder, unknown
        codec, unreachable scheduler...). The bytes written do not depend on ``jobs`` or ``scheduler``.
    """
    from mocapz.codecs import get_codec

    get_codec(codec)  # unknown codec: one error, not one per clip
    out_root = Path(output_dir)
    if out_root.exists() and not out_root.is_dir():
        raise MocapzError(f"{out_root}: output exists and is not a folder")
    jobs_list = plan(input_dir, out_root)
    out_root.mkdir(parents=True, exist_ok=True)
    worker = functools.partial(compress_clip, codec=codec, options=dict(options or {}), force=force)
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
