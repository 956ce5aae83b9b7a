"""Compiled (numba) kernel of :func:`mocapz.codecs.pga.so3.log_between`'s products ``mean.T @ rotation``, bit for
bit the numbers NumPy's ``@`` gives them (imported only when numba is installed; module-level functions, so that
numba's on-disk cache keeps them across processes).

NumPy multiplies a stack of 3 x 3 matrices one pair at a time through OpenBLAS's ``dgemm`` (about 95 ns a pair,
most of it the call: the Karcher mean of a 5,000-frame clip makes some two million of them). OpenBLAS's Haswell
kernels, which :mod:`mocapz._blas` pins, sum each element as a chain of fused multiply-adds from zero in the inner
index's order, ``fma(a2, b2, fma(a1, b1, fma(a0, b0, 0)))``; :func:`products_t` does the same with LLVM's ``fma``
(one rounding each, as the processor's instruction, or libm's where the processor has none): the same bits
(tests/test_so3_kernels.py compares them, and would fail on a BLAS that sums otherwise).

Shapes: ``mean`` ``(joints, 3, 3)``; ``rotations`` ``(samples, all joints, 3, 3)``; ``cols`` ``(joints,)`` the
joints of ``rotations`` each ``mean`` goes with; ``out`` ``(stop - start, joints, 3, 3)``.
"""

# ruff: noqa: ANN001
from __future__ import annotations

from numba import njit, types
from numba.extending import intrinsic

jit = njit(cache=True, nogil=True, error_model="numpy")


@intrinsic
def _fma(typingctx, a, b, c):  # noqa: ANN202, ARG001
    """``a * b + c`` rounded once (LLVM's ``llvm.fma.f64``)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # noqa: ANN202, ARG001
        return builder.fma(*args)

    return sig, codegen


@jit
def products_t(mean, rotations, cols, start: int, stop: int, out) -> None:
    """``out[s - start, j] = mean[j].T @ rotations[s, cols[j]]`` for the samples ``start <= s < stop``."""
    for s in range(start, stop):
        for j in range(cols.size):
            c = cols[j]
            for i in range(3):
                for k in range(3):
                    acc = _fma(mean[j, 0, i], rotations[s, c, 0, k], 0.0)
                    acc = _fma(mean[j, 1, i], rotations[s, c, 1, k], acc)
                    out[s - start, j, i, k] = _fma(mean[j, 2, i], rotations[s, c, 2, k], acc)
