"""Where work runs: :class:`Pool` runs a picklable function over a stream of items.

In this process (``jobs=1``), on a local process pool (``jobs=N``, :mod:`mocapz.parallel.processes`) or
on a ``dask.distributed`` cluster (``scheduler=ADDRESS``, or ``"local"`` for a LocalCluster on 127.0.0.1,
:mod:`mocapz.parallel.dask_engine`). At most ``window`` items are in flight at once, so memory stays
bounded however long the stream is, and each outcome carries the item's index, so callers can put results
back in input order. BLAS is limited to one thread in every mode (serial included), so results do not
depend on ``jobs`` or on the scheduler.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any

from mocapz.errors import OptionError
from mocapz.parallel.dask_engine import DaskEngine
from mocapz.parallel.processes import ProcessEngine
from mocapz.parallel.worker import Outcome, one_blas_thread


def available_cpus() -> int:
    """CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


class Pool:
    """Runs a function over items: in this process, on a local process pool, or on a Dask cluster.

    Args:
        jobs: worker processes for the local pool (``None``: one per available CPU; ``1``: no pool,
            run in this process). With ``scheduler="local"`` it is the number of Dask workers.
        scheduler: ``None`` for a local pool, ``"local"`` to start a Dask LocalCluster on 127.0.0.1, or
            a Dask scheduler address (``tcp://host:8786``). Needs ``pip install 'mocapz[dask]'``.
        max_items: upper bound on the number of items, to start no more workers than needed.
        preload: modules every worker imports before its first item (e.g.
            :func:`~mocapz.parallel.clip.clip_modules`), so the first items do not pay for imports; with a
            local pool the forkserver imports them once.

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
        self._processes: ProcessEngine | None = None
        self._dask: DaskEngine | None = None

    # -- lifecycle
    def __enter__(self) -> Pool:
        t0 = time.perf_counter()
        if self.mode == "processes":
            self._processes = ProcessEngine(self.workers, self.preload)
            self._processes.start()
        elif self.mode == "dask":
            assert self.scheduler is not None
            local_workers = self.jobs if self.jobs is not None else available_cpus()
            self._dask = DaskEngine(self.scheduler, local_workers, self.preload)
            self.workers = self._dask.start()
        self.startup_seconds = time.perf_counter() - t0
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._processes is not None:
            self._processes.close()
        if self._dask is not None:
            self._dask.close()

    @property
    def _client(self) -> Any:
        """The ``distributed.Client`` of an open Dask pool (``None`` otherwise)."""
        return self._dask.client if self._dask is not None else None

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

    # -- running
    def imap(self, fn: Callable[[Any], Any], items: Iterable[Any], window: int | None = None,
             ordered: bool = False) -> Iterator[Outcome]:
        """Run ``fn(item)`` for every item; yield an :class:`~mocapz.parallel.worker.Outcome` per item.

        ``fn`` must be picklable (a module-level function or a :func:`functools.partial` of one) and should
        return small values. ``items`` is consumed lazily: at most ``window`` items (default: twice the
        workers) are submitted and not yet yielded at any time, so a long stream never piles up in memory.
        Outcomes come in completion order, or in input order with ``ordered=True``. An exception raised
        by ``fn`` is returned in :attr:`Outcome.error`; a worker process that dies is reported as
        :class:`~mocapz.parallel.worker.WorkerCrashed` for the item(s) it was running and the pool carries on.
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
            assert self._processes is not None
            raw = self._processes.imap(fn, stream, window, held)
        else:
            assert self._dask is not None
            raw = self._dask.imap(fn, stream, window, held)
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
        with one_blas_thread():
            for i, item in stream:
                try:
                    value = fn(item)
                except Exception as exc:  # noqa: BLE001 - reported per item
                    yield Outcome(i, item, error=exc)
                else:
                    yield Outcome(i, item, value)

