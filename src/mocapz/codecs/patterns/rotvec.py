"""Rotation vectors of a joint's Euler angles over a clip, all frames at once, made continuous over time.

The pattern codec's value of a joint with three rotation channels is its local rotation vector (axis * angle,
radians; :mod:`.skeletal`). :func:`euler_rotvec` gives what scipy's ``Rotation.from_euler(order.upper(),
angles).as_rotvec()`` gives (intrinsic rotations, the canonical quaternion's angle in ``[0, pi]``; the same
numbers to rounding) without scipy's per-call work; :func:`continuous_rotvec` unrolls the angle past ``pi`` as
the clip turns on, with no Python loop over frames; :func:`rotvec_euler` turns them back into Euler angles, scipy's
``Rotation.from_rotvec(rv).as_euler(order.upper())`` to the bit (:mod:`.rotkernels` compiled ahead of time where
it is built, else scipy itself).
"""

from __future__ import annotations

import warnings

import numpy as np

from mocapz import _jit, aot

TINY_ANGLE = 1e-3  # below this the rotation vector's scale comes from its series (as scipy's)
FLIP_NORM = 1e-9  # a rotation vector this short has no direction to unroll along


def euler_rotvec(order: str, angles: np.ndarray) -> np.ndarray:
    """``(frames, 3)`` rotation vectors of intrinsic rotations about the axes of ``order`` (e.g. ``"ZYX"``, any
    case) by ``angles`` ``(frames, 3)`` radians, in that order."""
    half = 0.5 * np.asarray(angles, dtype=np.float64)
    c, s = np.cos(half), np.sin(half)
    q = np.zeros((half.shape[0], 4))  # (x, y, z, w): the first elementary rotation
    axis = "XYZ".index(order[0].upper())
    q[:, axis], q[:, 3] = s[:, 0], c[:, 0]
    for k in (1, 2):  # intrinsic: each next rotation composed on the right
        e = np.zeros_like(q)
        e[:, "XYZ".index(order[k].upper())], e[:, 3] = s[:, k], c[:, k]
        q = _compose(q, e)
    q[q[:, 3] < 0] *= -1.0  # the canonical quaternion: angle in [0, pi]
    v, w = q[:, :3], q[:, 3]
    vn = np.sqrt((v * v).sum(axis=1))
    angle = 2.0 * np.arctan2(vn, w)
    a2 = angle * angle
    small = angle <= TINY_ANGLE
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(small, 2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0, angle / np.sin(0.5 * angle))
    return v * scale[:, None]


def _compose(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton products ``p q`` of ``(n, 4)`` quaternions ``(x, y, z, w)``."""
    px, py, pz, pw = p.T
    qx, qy, qz, qw = q.T
    return np.stack([pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw,
                     pw * qw - px * qx - py * qy - pz * qz], axis=1)


def continuous_rotvec(rv: np.ndarray) -> np.ndarray:
    """Rotation vectors ``(frames, 3)`` made continuous over time (a turn past pi keeps growing): each frame's
    vector, or its other form ``v * (1 - 2 pi / |v|)`` (the same rotation), whichever lies nearer the frame
    before as it was made continuous.

    A frame's choice depends on the one before it only through which form that one took: per frame, the choice
    after either form of the frame before is worked out for all frames at once, and the chain of choices is then
    followed with running sums (a frame choosing the same after both forms starts the chain anew)."""
    out = np.array(rv, dtype=np.float64)
    norms = _norms(out)
    if len(out) < 2 or not (norms > 2.0).any():
        return out
    turns = norms > FLIP_NORM
    with np.errstate(divide="ignore", invalid="ignore"):
        alt = np.where(turns[:, None], out * (1.0 - 2.0 * np.pi / norms)[:, None], out)

    def nearer(prev: np.ndarray) -> np.ndarray:  # (frames - 1,) the other form is nearer the frame before's prev
        d_alt, d_own = _norms(alt[1:] - prev[:-1]), _norms(out[1:] - prev[:-1])
        return turns[1:] & (d_alt < d_own)

    after_own, after_alt = nearer(out), nearer(alt)  # the choice after the frame before kept its own form / not
    fixed = np.r_[True, after_own == after_alt]  # the first frame keeps its own form
    value = np.r_[False, after_own]  # where fixed: the form chosen
    flips = np.r_[False, after_own & ~after_alt].astype(np.int64)  # the other form before: its own now, and back
    last = np.maximum.accumulate(np.where(fixed, np.arange(len(out)), 0))
    flipped = np.cumsum(flips)
    chosen = value[last] ^ ((flipped - flipped[last]) % 2 == 1)
    out[chosen] = alt[chosen]
    return out


def _norms(v: np.ndarray) -> np.ndarray:
    """``(n,)`` lengths of ``(n, 3)`` vectors, each as ``np.linalg.norm`` of the one vector gives it (its dot
    product: the same bits, so the forms chosen are those of a frame-by-frame loop)."""
    return np.sqrt(np.matmul(v[:, None, :], v[:, :, None])[:, 0, 0])


def scipy_axes(order: str) -> np.ndarray:
    """``(3,)`` axis indices (0 x, 1 y, 2 z) of intrinsic rotations about ``order`` in the extrinsic form of
    scipy's Euler-angle method (the sequence reversed), as :func:`.rotkernels.rotvec_euler` takes them."""
    return np.array(["XYZ".index(c) for c in order.upper()[::-1]], dtype=np.int64)


def rotvec_euler(order: str, rv: np.ndarray) -> np.ndarray:
    """Euler angles ``(frames, 3)`` radians, intrinsic about the axes of ``order`` (e.g. ``"ZXY"``, any case), of
    rotation vectors ``rv`` ``(frames, 3)`` radians: scipy's ``Rotation.from_rotvec(rv).as_euler(order.upper())``
    bit for bit (the ahead-of-time kernel where built and numba not turned off, else scipy; angles in ``[-pi,
    pi]``, the middle one's range by the sequence, the third angle zero where the rotation is singular)."""
    rv = np.ascontiguousarray(rv, dtype=np.float64).reshape(-1, 3)
    kern = aot.kernels("rot") if _jit.enabled() else None
    if kern is not None:
        out = np.empty_like(rv)
        kern.rotvec_euler(rv, scipy_axes(order), False, out)
        return out
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy's gimbal-lock warning: the third angle zero, as documented
        from scipy.spatial.transform import Rotation  # noqa: I001 (on use: scipy.spatial loads slowly)
        return Rotation.from_rotvec(rv).as_euler(order.upper())
