"""Compiled (numba) forward kinematics: :func:`mocapz.model.kinematics.forward_kinematics`'s numbers, to the bit,
a frame at a time in one call (no ``(frames, joints, 3, 3)`` temporaries; about seven times faster on CMU clips).

The kernel takes NumPy's arithmetic step for step: the Euler rotations of :func:`~.kinematics.euler_rotations`
(the C library's ``cos`` and ``sin``, which NumPy's float64 ones call), and where NumPy hands a product to
OpenBLAS (its Haswell kernels, which :mod:`mocapz._blas` asks for on every x86-64 machine) the fused multiply-adds
of those kernels in their order: a 3 x 3 product ``c[a, b] = fma(a2, b2, fma(a1, b1, a0 * b0))`` (``@`` on the
parents' rotations, an ASF joint's axis frame), a rotation times an end site's offset ``fma(a2, b2, fma(a0, b0,
a1 * b1))`` (``@`` on a vector); a rotation times a joint's translation as ``np.einsum("fab,fb->fa")`` sums it,
``(a0 b0 + a2 b2) + a1 b1``. ``fma`` is LLVM's (one rounding, whatever the processor). Imported only where numba
is installed; :mod:`mocapz.aot` compiles it ahead of time (alias ``fk``), and kinematics takes it only from there
(loading numba just in time would cost more than it saves). Shapes: ``channels`` ``(frames, channels)`` (file
units; angles times ``scale`` are radians), ``pos`` ``(frames, points, 3)``, ``rot`` ``(frames, joints, 3, 3)``
(or ``(1, joints, 3, 3)`` of work space where ``keep`` is False: the positions alone).
"""

# ruff: noqa: ANN001, PLR0913
from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

jit = njit(cache=True, nogil=True, error_model="numpy")


@intrinsic
def fma(typingctx, a, b, c):  # noqa: ARG001  (numba's intrinsic protocol)
    """``a * b + c`` rounded once (LLVM's ``llvm.fma.f64``)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # noqa: ARG001
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


@jit
def _local(channels, f: int, j: int, scale: float, rot_cols, rot_axes, n_rot, turned, axis, loc, tmp) -> None:
    """Joint ``j``'s local rotation at frame ``f`` into ``loc`` (3, 3): :func:`~.kinematics.local_rotations`."""
    for a in range(3):
        for b in range(3):
            loc[a, b] = 1.0 if a == b else 0.0
    k = n_rot[j]
    if k:
        ax = rot_axes[j, 0]
        t = channels[f, rot_cols[j, 0]] * scale
        c, s = math.cos(t), math.sin(t)
        i, m = (ax + 1) % 3, (ax + 2) % 3
        loc[ax, ax] = 1.0
        loc[i, i] = c
        loc[m, m] = c
        loc[i, m] = -s
        loc[m, i] = s
        for q in range(1, k):  # R @ R_axis(t) mixes two columns of R, as euler_rotations does
            ax = rot_axes[j, q]
            i, m = (ax + 1) % 3, (ax + 2) % 3
            t = channels[f, rot_cols[j, q]] * scale
            c, s = math.cos(t), math.sin(t)
            for a in range(3):
                ci, cm = loc[a, i], loc[a, m]
                loc[a, i] = c * ci + s * cm
                loc[a, m] = c * cm - s * ci
    if turned[j]:  # an ASF joint's axis frame: a @ loc @ a.T
        for a in range(3):
            for b in range(3):
                tmp[a, b] = fma(axis[j, a, 2], loc[2, b], fma(axis[j, a, 1], loc[1, b], axis[j, a, 0] * loc[0, b]))
        for a in range(3):
            for b in range(3):
                loc[a, b] = fma(tmp[a, 2], axis[j, b, 2], fma(tmp[a, 1], axis[j, b, 1], tmp[a, 0] * axis[j, b, 0]))


@jit
def forward(channels, scale: float, parents, rot_cols, rot_axes, n_rot, turned, axis, pos_cols, offsets, end_joint,
            end_off, pos, rot, keep: bool) -> None:
    """Positions ``pos`` and (``keep``) global rotations ``rot`` of every frame. Per joint: ``parents``,
    ``rot_cols`` and ``rot_axes`` ``(joints, 3)`` its first ``n_rot`` rotation channels' columns and axes (0 x,
    1 y, 2 z) in order, ``turned`` and ``axis`` ``(joints, 3, 3)`` its ASF axis frame, ``pos_cols`` ``(joints,
    3)`` the column of each position channel (-1: ``offsets``' value); ``end_joint`` and ``end_off`` ``(end
    sites, 3)`` the end sites."""
    n = parents.size
    loc = np.empty((3, 3))
    tmp = np.empty((3, 3))
    tr = np.empty(3)
    for f in range(channels.shape[0]):
        g = rot[f] if keep else rot[0]
        for j in range(n):
            _local(channels, f, j, scale, rot_cols, rot_axes, n_rot, turned, axis, loc, tmp)
            for a in range(3):
                tr[a] = channels[f, pos_cols[j, a]] if pos_cols[j, a] >= 0 else offsets[j, a]
            p = parents[j]
            if p < 0:
                for a in range(3):
                    for b in range(3):
                        g[j, a, b] = loc[a, b]
                    pos[f, j, a] = tr[a]
                continue
            for a in range(3):
                for b in range(3):
                    g[j, a, b] = fma(g[p, a, 2], loc[2, b], fma(g[p, a, 1], loc[1, b], g[p, a, 0] * loc[0, b]))
                pos[f, j, a] = pos[f, p, a] + ((g[p, a, 0] * tr[0] + g[p, a, 2] * tr[2]) + g[p, a, 1] * tr[1])
        for e in range(end_joint.size):
            j = end_joint[e]
            for a in range(3):
                pos[f, n + e, a] = pos[f, j, a] + fma(g[j, a, 2], end_off[e, 2],
                                                      fma(g[j, a, 0], end_off[e, 0], g[j, a, 1] * end_off[e, 1]))


@jit
def local(channels, scale: float, rot_cols, rot_axes, n_rot, turned, axis, out) -> None:
    """The local rotations ``out`` ``(frames, joints, 3, 3)`` alone (:func:`~.kinematics.local_rotations`), the
    arguments as :func:`forward`'s."""
    tmp = np.empty((3, 3))
    for f in range(channels.shape[0]):
        for j in range(n_rot.size):
            _local(channels, f, j, scale, rot_cols, rot_axes, n_rot, turned, axis, out[f, j], tmp)
