"""One BLAS kernel set on every x86-64 machine, so that the same input and options give the same bytes.

NumPy's OpenBLAS picks its kernels from the CPU it runs on (Haswell, SkylakeX, Zen...), and kernels sum
in different orders: the lossy encoders' float64 results (PCA bases, least squares, the PGA's IK) then
differ in the last bits from one machine to the next, and so do the ``.mcz`` bytes. mocapz asks OpenBLAS
for its Haswell kernels (AVX2, every x86-64 CPU of the last decade) before NumPy is first imported. A user
who sets ``OPENBLAS_CORETYPE`` keeps their choice; a process that imported NumPy before mocapz keeps the
kernels NumPy already chose (then bytes may differ from other machines', never from run to run).
"""

from __future__ import annotations

import os
import platform
import sys


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
