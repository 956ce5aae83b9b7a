"""SO(3) tools in plain numpy, batched over any leading axes.

Rotation vectors ``w`` have shape ``(..., 3)`` (radians, axis * angle); matrices ``(..., 3, 3)``.
scipy's ``Rotation`` is used for Euler conversions elsewhere; these hot paths (exp, log, right
Jacobian, intrinsic mean) are written here because they run inside the IK loop. :func:`log_between`'s products
are :mod:`.so3kernels`' where the kernels are compiled ahead of time (the same bits as NumPy's).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mocapz import _jit, aot

_EPS = 1e-8
MEAN_ROWS = 512  # samples per step of the Karcher mean's average (its temporaries: peak memory)


def hat(w: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrices ``(..., 3, 3)`` with ``hat(w) @ v == cross(w, v)``."""
    k = np.zeros((*w.shape[:-1], 3, 3), dtype=np.result_type(w.dtype, np.float64))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    return k


def exp(w: np.ndarray) -> np.ndarray:
    """Rodrigues' formula: rotation matrices from rotation vectors."""
    w = np.asarray(w, dtype=np.float64)
    th2 = np.einsum("...i,...i->...", w, w)
    th = np.sqrt(th2)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th2 / 6.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(ths)) / (ths * ths))
    k = hat(w)
    return np.eye(3) + a[..., None, None] * k + b[..., None, None] * (k @ k)


def log(r: np.ndarray) -> np.ndarray:
    """Rotation vectors (angle in [0, pi]) from rotation matrices, stable near 0 and pi."""
    r = np.asarray(r, dtype=np.float64)
    tr = r[..., 0, 0] + r[..., 1, 1] + r[..., 2, 2]  # np.trace's sum, in its order (the same bits, 2.5x faster)
    cos = np.clip((tr - 1.0) / 2.0, -1.0, 1.0)
    th = np.arccos(cos)
    vee = np.empty(r.shape[:-1])
    np.subtract(r[..., 2, 1], r[..., 1, 2], out=vee[..., 0])
    np.subtract(r[..., 0, 2], r[..., 2, 0], out=vee[..., 1])
    np.subtract(r[..., 1, 0], r[..., 0, 1], out=vee[..., 2])
    sin = np.sin(th)
    small = th < 1e-4
    near_pi = th > np.pi - 1e-3
    fac = np.where(small, 0.5 + th * th / 12.0, th / (2.0 * np.where(small | near_pi, 1.0, sin)))
    w = fac[..., None] * vee
    if np.any(near_pi):  # per rotation: computed on those near pi only
        w[near_pi] = _log_near_pi(r[near_pi], th[near_pi], vee[near_pi])
    return w


def _log_near_pi(r: np.ndarray, th: np.ndarray, vee: np.ndarray) -> np.ndarray:
    # R + I = 2 n n^T + O(pi - th): take the largest column for the axis, sign from vee.
    b = (r + np.eye(3)) / 2.0
    diag = np.diagonal(b, axis1=-2, axis2=-1)
    i = np.argmax(diag, axis=-1)
    col = np.take_along_axis(b, i[..., None, None].repeat(3, -1), axis=-2)[..., 0, :]
    n = col / np.sqrt(np.maximum(np.take_along_axis(diag, i[..., None], -1), _EPS))
    sign = np.where(np.einsum("...i,...i->...", n, vee) < 0, -1.0, 1.0)
    return n * (sign * th)[..., None]


def right_jacobian(w: np.ndarray) -> np.ndarray:
    """``J_r(w)`` with ``exp(w + d) ~= exp(w) @ exp(J_r(w) @ d)``, shape ``(..., 3, 3)``."""
    th2 = np.einsum("...i,...i->...", w, w)
    th = np.sqrt(th2)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    a = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(ths)) / (ths * ths))
    b = np.where(small, 1.0 / 6.0 - th2 / 120.0, (ths - np.sin(ths)) / (ths**3))
    k = hat(w)
    return np.eye(3) - a[..., None, None] * k + b[..., None, None] * (k @ k)


def karcher_mean(r: np.ndarray, iterations: int = 50, tol: float = 1e-12) -> np.ndarray:
    """Intrinsic (Karcher / Frechet) mean over axis 0 of rotations ``(samples, ..., 3, 3)``.

    Iterates ``mu <- mu exp(mean_i log(mu^T r_i))`` on each mean until its update is below ``tol`` radians (the
    means that have converged are left out of the next iterations: on a clip's joints most settle in a few, a
    few take a dozen). A mean's iterations are the same numbers whichever others run beside it.
    """
    mu = _chordal_mean(r)
    lead = mu.shape[:-2]
    mu = mu.reshape(-1, 3, 3)
    samples = r.reshape(r.shape[0], -1, 3, 3)
    active = np.arange(mu.shape[0])
    for _ in range(iterations):
        if not active.size:
            break
        m = mu[active]
        t = log_between(m, samples, None if active.size == mu.shape[0] else active).mean(axis=0)
        mu[active] = m @ exp(t)
        active = active[~(np.linalg.norm(t, axis=-1) < tol)]
    return mu.reshape(*lead, 3, 3)


def log_between(mean: np.ndarray, rotations: np.ndarray, columns: np.ndarray | None = None) -> np.ndarray:
    """``log(mean^T @ rotations[:, columns])`` ``(samples, ..., 3)`` of rotations ``(samples, ..., 3, 3)`` about
    ``mean`` ``(..., 3, 3)`` (``columns``: those of the second axis, default all), :data:`MEAN_ROWS` samples at a
    time: the temporaries of a few hundred samples, not of a clip (the same numbers)."""
    mt = np.swapaxes(mean, -1, -2)[None]
    n = rotations.shape[0]
    out = np.empty((n, *mt.shape[1:-1]))
    kern = _products_kernel(mean, rotations)
    if kern is not None:
        cols = np.arange(mean.shape[0], dtype=np.int64) if columns is None \
            else np.ascontiguousarray(columns, dtype=np.int64)
        m = np.ascontiguousarray(mean, dtype=np.float64)
    for a in range(0, n, MEAN_ROWS):
        if kern is not None:
            prod = np.empty((min(n, a + MEAN_ROWS) - a, *mean.shape))
            kern.products_t(m, rotations, cols, a, a + len(prod), prod)
        else:
            prod = mt @ (rotations[a:a + MEAN_ROWS] if columns is None else rotations[a:a + MEAN_ROWS, columns])
        out[a:a + MEAN_ROWS] = log(prod)
    return out


def _products_kernel(mean: np.ndarray, rotations: np.ndarray) -> Any:
    """:mod:`.so3kernels` compiled ahead of time, where they are and take these arrays (``mean`` ``(joints, 3,
    3)``, ``rotations`` ``(samples, joints, 3, 3)`` float64, any strides), else None (NumPy's products, the same
    bits: no numba loaded for them)."""
    if not _jit.enabled() or mean.ndim != 3 or rotations.ndim != 4 or rotations.dtype != np.float64:
        return None
    return aot.kernels("so3")


def _chordal_mean(r: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(r.mean(axis=0))
    d = np.sign(np.linalg.det(u @ vt))
    u[..., :, 2] *= d[..., None]
    return u @ vt
