"""The local engine: items run on a :class:`concurrent.futures.ProcessPoolExecutor` of this machine.

Used by :class:`mocapz.parallel.pool.Pool` for ``jobs=N`` (N > 1). Workers start from a forkserver that
has imported the preload modules once; a worker that dies (crash in native code, out of memory) costs
only the item it was running, reported as :class:`~mocapz.parallel.worker.WorkerCrashed`.
"""

from __future__ import annotations

import functools
import multiprocessing
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from mocapz.parallel.worker import Outcome, WorkerCrashed, call_in_worker, import_modules, to_outcome


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


def _done_outcome(i: int, item: Any, fut: Future[Any]) -> Outcome:
    exc = fut.exception()
    return Outcome(i, item, error=exc) if exc is not None else to_outcome(i, item, fut.result())


class ProcessEngine:
    """A pool of ``workers`` local processes, each importing ``preload`` before its first item.

    :meth:`start` starts every worker; :meth:`imap` runs items on them; :meth:`close` shuts them down.
    """

    def __init__(self, workers: int, preload: Sequence[str] = ()) -> None:
        self.workers = workers
        self.preload = tuple(preload)
        self._executor: ProcessPoolExecutor | None = None

    def start(self) -> None:
        self._executor = self._new_executor(self.workers)
        # Start every worker now (one warm-up task each: the pool starts a process per task while
        # none is idle), so start-up is measured here and the first items do not wait for it.
        wait([self._executor.submit(import_modules, self.preload) for _ in range(self.workers)])

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None

    def _new_executor(self, workers: int) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=workers, mp_context=_mp_context(self.preload))

    def imap(self, fn: Callable[[Any], Any], stream: Iterator[tuple[int, Any]], window: int,
             held: Callable[[], int]) -> Iterator[Outcome]:
        """Outcomes of ``fn`` over ``(index, item)`` pairs, in completion order, with at most
        ``window - held()`` items running at once (see :meth:`mocapz.parallel.pool.Pool.imap`)."""
        call = functools.partial(call_in_worker, fn)
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
                    yield _done_outcome(i, item, fut)
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
                    finished.append(_done_outcome(i, item, fut))
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
                return to_outcome(i, item, solo.submit(call, item).result())
            except BrokenProcessPool:
                return Outcome(i, item, error=WorkerCrashed("the worker process died while running it "
                                                            "(crash in native code, or out of memory)"))
            except Exception as exc:  # noqa: BLE001 - reported per item
                return Outcome(i, item, error=exc)
