"""What runs inside a worker process, and what comes back from it: :class:`Outcome`.

Shared by every engine (:mod:`mocapz.parallel.pool` serially, :mod:`mocapz.parallel.processes` on a local
process pool, :mod:`mocapz.parallel.dask_engine` on a Dask cluster):

* :func:`call_in_worker` wraps the user's function in a worker: BLAS limited to one thread (the same
  numerics in every mode, so the output bytes do not depend on the parallelism), and an exception raised
  by the function sent back in a form that always survives pickling; :func:`to_outcome` turns what came
  back into an :class:`Outcome` in the calling process.
* :func:`import_modules` is the warm-up task (imports before the first item).
* :class:`WorkerCrashed` and :class:`WorkerError` are the errors an engine reports for an item.
"""

from __future__ import annotations

import contextlib
import pickle
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from mocapz.errors import FormatError, MocapzError


class WorkerCrashed(MocapzError):
    """A worker process died while running an item (crash in native code, or killed for memory)."""


class WorkerError(MocapzError):
    """An exception raised in a worker that could not be sent back as itself (not picklable)."""


@dataclass(frozen=True)
class Outcome:
    """The result of one item run by :meth:`Pool.imap <mocapz.parallel.pool.Pool.imap>`: ``value`` or the
    ``error`` it raised."""

    index: int
    item: Any
    value: Any = None
    error: BaseException | None = None


def one_blas_thread() -> contextlib.AbstractContextManager[Any]:
    """BLAS/OpenMP limited to one thread (as a context manager; the limit applies as soon as it is made)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        return contextlib.nullcontext()
    return threadpool_limits(limits=1)  # applied at once (the worker's limit for good, :func:`_limit_blas_once`)


_BLAS_LIMITED = False


def _limit_blas_once() -> None:
    """Limit BLAS/OpenMP to one thread in this (worker) process, once, for good: same numerics in every mode."""
    global _BLAS_LIMITED
    if _BLAS_LIMITED:
        return
    _BLAS_LIMITED = True
    one_blas_thread()  # never exited: the limit stays for the worker's life


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


def call_in_worker(fn: Callable[[Any], Any], item: Any) -> Any:
    """``fn(item)`` in a worker process, with one BLAS thread; an exception is returned, not raised.

    Submit ``functools.partial(call_in_worker, fn)``; pass what comes back to :func:`to_outcome`.
    """
    _limit_blas_once()
    try:
        return fn(item)
    except Exception as exc:  # noqa: BLE001 - sent back, turned into Outcome.error
        return _Raised.of(exc)


def to_outcome(i: int, item: Any, value: Any) -> Outcome:
    """The :class:`Outcome` of item ``i`` from what :func:`call_in_worker` returned for it."""
    return Outcome(i, item, error=value.rebuild()) if isinstance(value, _Raised) else Outcome(i, item, value)


def import_modules(modules: Sequence[str]) -> None:
    """Import modules in a worker (warm-up before the first item); unknown ones are skipped."""
    import importlib

    for name in modules:
        with contextlib.suppress(ImportError):
            importlib.import_module(name)
