"""One BLAS kernel set on every x86-64 machine, so that the same input and options give the same bytes.

NumPy's OpenBLAS picks its kernels from the CPU it runs on (Haswell, SkylakeX, Zen...), and kernels sum
in different orders: the lossy encoders' float64 results (PCA bases, least squares, the PGA's IK) then
differ in the last bits from one machine to the next, and so do the ``.mcz`` bytes. mocapz asks OpenBLAS
for its Haswell kernels (AVX2, every x86-64 CPU of the last decade) before NumPy is first imported. A user
who sets ``OPENBLAS_CORETYPE`` keeps their choice; a process that imported NumPy before mocapz keeps the
kernels NumPy already chose (then bytes may differ from other machines', never from run to run).
"""

from __future__ import annotations

import contextlib
import functools
import os
import platform
import sys
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])
_CONTROLLER: list[Any] = []  # threadpoolctl's controller, made on first use (after NumPy has loaded its BLAS)


def pin_openblas_kernels() -> None:
    """Set ``OPENBLAS_CORETYPE=Haswell`` on x86-64 CPUs with AVX2 if NumPy is not imported yet."""
    if "numpy" in sys.modules or "OPENBLAS_CORETYPE" in os.environ:
        return
    if platform.machine().lower() not in ("x86_64", "amd64") or not _has_avx2():
        return
    os.environ["OPENBLAS_CORETYPE"] = "Haswell"


def _has_avx2() -> bool:
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("flags"):
                    return " avx2" in line
    except OSError:
        return False
    return False


def one_thread() -> contextlib.AbstractContextManager[Any]:
    """A context in which BLAS (and OpenMP) run on one thread. The codecs' matrices are small: spread over
    threads they are slower, far slower on a busy machine (threads spin waiting for a core: an SVD of 4,906 x 93
    took 1.2-3.0 s with two threads on a loaded two-core machine, 0.09 s with one), and some sums change
    order with the thread count, so one thread also gives the same bytes on every machine."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        return contextlib.nullcontext()
    if not _CONTROLLER:
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0].limit(limits=1)  # type: ignore[no-any-return]


def on_one_thread(fn: F) -> F:
    """``fn`` run inside :func:`one_thread`."""

    @functools.wraps(fn)
    def run(*args: Any, **kwargs: Any) -> Any:
        with one_thread():
            return fn(*args, **kwargs)

    return run  # type: ignore[return-value]
