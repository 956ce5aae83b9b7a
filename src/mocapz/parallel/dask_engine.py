"""The Dask engine: items run on a ``dask.distributed`` cluster (needs ``pip install 'mocapz[dask]'``).

Used by :class:`mocapz.parallel.pool.Pool` when it is given a scheduler: an address (``tcp://host:8786``)
to connect to, or ``"local"`` to start a :class:`~distributed.LocalCluster` on 127.0.0.1 (one
single-threaded worker process each, with a scratch folder removed on close).

On a real cluster the workers must have the same mocapz installed and see the input and output folders at
the same paths (a shared file system): workers read the clips and write the ``.mcz`` files themselves;
only file names and small result records travel through the scheduler.
"""

from __future__ import annotations

import contextlib
import functools
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from mocapz.errors import MocapzError, OptionError
from mocapz.parallel.worker import Outcome, WorkerCrashed, call_in_worker, import_modules, to_outcome


class DaskEngine:
    """A Dask client, and the LocalCluster it runs on for ``scheduler="local"``.

    Args:
        scheduler: a Dask scheduler address, or ``"local"``.
        local_workers: the number of LocalCluster workers (only for ``"local"``).
        preload: modules every worker imports before its first item.

    :meth:`start` connects (or starts the cluster) and returns the number of worker threads; :meth:`imap`
    runs items; :meth:`close` disconnects and stops what :meth:`start` started.
    """

    def __init__(self, scheduler: str, local_workers: int, preload: Sequence[str] = ()) -> None:
        self.scheduler = scheduler
        self.local_workers = local_workers
        self.preload = tuple(preload)
        self.client: Any = None
        self.cluster: Any = None
        self.scratch: str | None = None

    def start(self) -> int:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise OptionError("--scheduler needs Dask: pip install 'mocapz[dask]' "
                              "(or pip install 'dask[distributed]')") from None
        import logging

        if self.scheduler == "local":
            n = self.local_workers
            self.scratch = tempfile.mkdtemp(prefix="mocapz-dask-")  # workers' scratch space, removed on close
            import dask

            with dask.config.set({"temporary-directory": self.scratch}):
                self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                                            dashboard_address=None, silence_logs=logging.CRITICAL,
                                            local_directory=self.scratch)
            self.client = Client(self.cluster)
            self.client.wait_for_workers(n)
        else:
            try:
                self.client = Client(self.scheduler, timeout="20s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise MocapzError(f"cannot reach Dask scheduler {self.scheduler}: {exc}") from None
        if self.preload:
            self.client.run(import_modules, list(self.preload))
        threads = sum(self.client.nthreads().values())
        return max(1, threads)

    def close(self) -> None:
        if self.client is not None:
            with contextlib.suppress(Exception):
                self.client.close()
            self.client = None
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close()
            self.cluster = None
        if self.scratch is not None:
            shutil.rmtree(self.scratch, ignore_errors=True)
            self.scratch = None

    def imap(self, fn: Callable[[Any], Any], stream: Iterator[tuple[int, Any]], window: int,
             held: Callable[[], int]) -> Iterator[Outcome]:
        """Outcomes of ``fn`` over ``(index, item)`` pairs, in completion order, with at most
        ``window - held()`` items submitted at once (see :meth:`mocapz.parallel.pool.Pool.imap`)."""
        from distributed import as_completed

        try:
            from distributed.scheduler import KilledWorker
        except ImportError:  # pragma: no cover - older layouts
            from distributed import KilledWorker  # type: ignore[no-redef,attr-defined]

        client = self.client
        call = functools.partial(call_in_worker, fn)
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
                outcome = to_outcome(i, item, fut.result())
            except KilledWorker:
                outcome = Outcome(i, item, error=WorkerCrashed("Dask workers died while running it "
                                                               "(crash in native code, or out of memory)"))
            except Exception as exc:  # noqa: BLE001 - reported per item
                outcome = Outcome(i, item, error=exc)
            fut.release()
            yield outcome
            refill()
