"""Compiled (numba) kernels of the closed loop of :mod:`mocapz.codecs.correction.chain` (imported only when
numba is installed; module-level functions, so that numba's on-disk cache keeps them across processes).

They do, one frame at a time in one pass, what :meth:`~mocapz.codecs.correction.chain.Chain.quantise` does
over frames with a dozen NumPy steps per joint (each a pass over ``(frames, 3, 3)`` arrays): the decoded
joint's position, the bone's turn toward the original child, the local rotation wanted under the decoded
parent and its Euler angles nearest the original's (:func:`goal_angles`), then the decoded joint's global
rotation (:func:`compose`). The results agree with the NumPy path to float rounding
(tests/test_correction_jit.py).

Shapes: ``gp``, ``gj`` ``(frames, 3, 3)`` the decoded global rotations of a joint's parent and of the joint (a
root's ``gp`` is not read), ``p`` ``(frames, joints, 3)`` decoded positions (file units), angles in the file's
angle unit (``scale`` converts them to radians).
"""

# ruff: noqa: ANN001, ANN202
from __future__ import annotations

import math

import numpy as np
from numba import njit

from mocapz.codecs.pga.ikkernels import mul33

jit = njit(cache=True, nogil=True, error_model="numpy")


@jit
def _axis_rot(axis: int, t: float, out: np.ndarray) -> None:
    """Rotation about coordinate axis ``axis`` by ``t`` radians into ``out`` (3, 3)."""
    c, s = math.cos(t), math.sin(t)
    i, k = (axis + 1) % 3, (axis + 2) % 3
    for a in range(3):
        for b in range(3):
            out[a, b] = 0.0
    out[axis, axis] = 1.0
    out[i, i] = c
    out[k, k] = c
    out[i, k] = -s
    out[k, i] = s


@jit
def _euler(angles: np.ndarray, axes: np.ndarray, r: np.ndarray) -> None:
    """Intrinsic Euler rotation of ``angles`` (radians) about ``axes`` (one to three of them) into ``r`` (3, 3), as
    :func:`mocapz.model.kinematics.euler_rotations`."""
    _axis_rot(axes[0], angles[0], r)
    for k in range(1, axes.size):
        axis = axes[k]
        i, j = (axis + 1) % 3, (axis + 2) % 3
        c, s = math.cos(angles[k]), math.sin(angles[k])
        for a in range(3):
            ci, cj = r[a, i], r[a, j]
            r[a, i] = c * ci + s * cj
            r[a, j] = c * cj - s * ci


@jit
def _mul_t(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """``a.T @ b``."""
    for i in range(3):
        for k in range(3):
            out[i, k] = a[0, i] * b[0, k] + a[1, i] * b[1, k] + a[2, i] * b[2, k]


@jit
def _mul_t_row(a, f: int, b: np.ndarray, out: np.ndarray) -> None:
    """``a[f].T @ b`` (``a`` ``(frames, 3, 3)``), indexed in place: no view of ``a[f]`` made per frame."""
    for i in range(3):
        for k in range(3):
            out[i, k] = a[f, 0, i] * b[0, k] + a[f, 1, i] * b[1, k] + a[f, 2, i] * b[2, k]


@jit
def _mul_rows(a, f: int, b: np.ndarray, out) -> None:
    """``out[f] = a[f] @ b`` (``a``, ``out`` ``(frames, 3, 3)``), indexed in place: the same sums as :func:`mul33`."""
    for i in range(3):
        for j in range(3):
            out[f, i, j] = a[f, i, 0] * b[0, j] + a[f, i, 1] * b[1, j] + a[f, i, 2] * b[2, j]


@jit
def place(gp, p, j: int, parent: int, trans) -> None:
    """Decoded position of joint ``j`` from its local translations ``trans`` ``(frames, 3)``."""
    for f in range(trans.shape[0]):
        for a in range(3):
            if parent < 0:
                p[f, j, a] = trans[f, a]
            else:
                p[f, j, a] = p[f, parent, a] + gp[f, a, 0] * trans[f, 0] \
                    + gp[f, a, 1] * trans[f, 1] + gp[f, a, 2] * trans[f, 2]


@jit
def goal_angles(gp, p, j: int, parent: int, goal_rot, positions, aim: int, cos_most: float, axis,
                turned: bool, ijk, sign: float, scale: float, values, near, period: float, out, rows) -> None:
    """Euler angles ``out`` ``(frames, 3)`` (file unit, of the two solutions and every turn the nearest the
    original's: ``values`` ``(frames, columns)`` at the columns ``near``) of the local rotation that, under the
    decoded parent, gives joint ``j``'s original global rotation ``goal_rot`` ``(frames, 3, 3)``, its bone first
    turned (at most ``acos(cos_most)``) to point from the decoded joint at the original child ``aim`` (-1: none);
    on the frames ``rows`` only (each frame on its own)."""
    goal = np.empty((3, 3))
    turn = np.empty((3, 3))
    tmp = np.empty((3, 3))
    r = np.empty((3, 3))
    kk = np.empty((3, 3))
    i, jj, k = ijk[0], ijk[1], ijk[2]
    half = period / 2.0
    for row in range(rows.size):
        f = rows[row]
        for a in range(3):
            for b in range(3):
                goal[a, b] = goal_rot[f, a, b]
        if aim >= 0:
            a0, a1, a2 = (positions[f, aim, 0] - positions[f, j, 0], positions[f, aim, 1] - positions[f, j, 1],
                          positions[f, aim, 2] - positions[f, j, 2])
            b0, b1, b2 = positions[f, aim, 0] - p[f, j, 0], positions[f, aim, 1] - p[f, j, 1], \
                positions[f, aim, 2] - p[f, j, 2]
            na = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
            nb = math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
            if na > 0 and nb > 0:
                u0, u1, u2 = a0 / na, a1 / na, a2 / na
                w0, w1, w2 = b0 / nb, b1 / nb, b2 / nb
                v0, v1, v2 = u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0
                c = u0 * w0 + u1 * w1 + u2 * w2
                if c > cos_most:
                    kk[0, 0], kk[0, 1], kk[0, 2] = 0.0, -v2, v1
                    kk[1, 0], kk[1, 1], kk[1, 2] = v2, 0.0, -v0
                    kk[2, 0], kk[2, 1], kk[2, 2] = -v1, v0, 0.0
                    mul33(kk, kk, tmp)
                    h = 1.0 / (1.0 + max(c, -0.5))
                    for a in range(3):
                        for b in range(3):
                            turn[a, b] = (1.0 if a == b else 0.0) + kk[a, b] + tmp[a, b] * h
                    mul33(turn, goal, tmp)
                    goal[:, :] = tmp
        if parent >= 0:
            _mul_t_row(gp, f, goal, r)
        else:
            r[:, :] = goal
        if turned:
            _mul_t(axis, r, tmp)
            mul33(tmp, axis, r)
        x = sign * r[i, k]
        mid = math.asin(min(1.0, max(-1.0, x)))
        if abs(x) > 1.0 - 1e-12:
            first = math.atan2(sign * r[k, jj], r[jj, jj])
            last = 0.0
        else:
            first = math.atan2(-sign * r[jj, k], r[k, k])
            last = math.atan2(-sign * r[i, jj], r[i, i])
        s0, s1, s2 = first / scale, mid / scale, last / scale
        t0, t1, t2 = s0 + half, half - s1, s2 + half
        n0, n1, n2 = values[f, near[0]], values[f, near[1]], values[f, near[2]]
        s0 += period * np.rint((n0 - s0) / period)
        s1 += period * np.rint((n1 - s1) / period)
        s2 += period * np.rint((n2 - s2) / period)
        t0 += period * np.rint((n0 - t0) / period)
        t1 += period * np.rint((n1 - t1) / period)
        t2 += period * np.rint((n2 - t2) / period)
        if abs(t0 - n0) + abs(t1 - n1) + abs(t2 - n2) < abs(s0 - n0) + abs(s1 - n1) + abs(s2 - n2):
            s0, s1, s2 = t0, t1, t2
        out[f, 0], out[f, 1], out[f, 2] = s0, s1, s2


@jit
def compose(gj, gp, parent: int, values, scale: float, axes, axis, turned: bool, rows) -> None:
    """Decoded global rotation of a joint into ``gj``: the decoded parent's ``gp`` (a root: none, ``parent``
    < 0) times the local rotation of the decoded Euler ``values`` ``(frames, axes)`` (file unit) about ``axes``
    (three, or the one or two of an ASF hinge), in the joint's ``axis`` frame when ``turned`` (ASF); on the
    frames ``rows`` only."""
    loc = np.empty((3, 3))
    tmp = np.empty((3, 3))
    ang = np.empty(axes.size)
    for row in range(rows.size):
        f = rows[row]
        for a in range(axes.size):
            ang[a] = values[f, a] * scale
        _euler(ang, axes, loc)
        if turned:
            mul33(axis, loc, tmp)
            for a in range(3):
                for b in range(3):
                    loc[a, b] = tmp[a, 0] * axis[b, 0] + tmp[a, 1] * axis[b, 1] + tmp[a, 2] * axis[b, 2]
        if parent >= 0:
            _mul_rows(gp, f, loc, gj)
        else:
            gj[f, :, :] = loc


@jit
def remainder(a: float, b: float) -> float:
    """NumPy's ``np.mod`` of floats (``b > 0``): ``fmod``, then the divisor's sign."""
    mod = np.fmod(a, b)
    if mod != 0.0:
        if (b < 0.0) != (mod < 0.0):
            mod += b
    else:
        mod = math.copysign(0.0, b)
    return mod


@jit
def _about(e, v, u) -> float:
    """The angle about unit axis ``e`` (3,) that brings ``v``'s component across ``e`` onto ``u``'s (one frame of
    :func:`.hinge._about`)."""
    ve = v[0] * e[0] + v[1] * e[1] + v[2] * e[2]
    ue = u[0] * e[0] + u[1] * e[1] + u[2] * e[2]
    vp0, vp1, vp2 = v[0] - ve * e[0], v[1] - ve * e[1], v[2] - ve * e[2]
    up0, up1, up2 = u[0] - ue * e[0], u[1] - ue * e[1], u[2] - ue * e[2]
    c0, c1, c2 = vp1 * up2 - vp2 * up1, vp2 * up0 - vp0 * up2, vp0 * up1 - vp1 * up0
    return math.atan2(c0 * e[0] + c1 * e[1] + c2 * e[2], vp0 * up0 + vp1 * up1 + vp2 * up2)


@jit
def _nearest(angle: float, near: float) -> float:
    """``angle`` plus the whole turns that bring it nearest ``near`` (radians)."""
    return angle + 2.0 * np.pi * np.rint((near - angle) / (2.0 * np.pi))


@jit
def hinge_residual(gp, p, j: int, child: int, positions, axis, bone, axes, scale: float, values, cols, base,
                   period: float, max_turn: float, goal, rows) -> None:
    """:meth:`.chain.Chain._hinge_residual` (:func:`.hinge.aim`) frame by frame: the angles about the one or two
    ``axes`` of hinge ``j`` (columns ``cols``, in rotation order) that, under the decoded parent (``gp``) and from
    the decoded joint (``p``), turn its ``bone`` (3,) (in its ``axis`` frame) toward the original point ``child``,
    nearest the original angles (``values``; kept where the bone cannot reach or would turn over ``max_turn``
    radians), as residuals against ``base``, wrapped, into ``goal`` ``(frames, columns)``; on the frames ``rows``
    only (each frame on its own)."""
    n = axes.size
    half = period / 2.0
    e = np.zeros((2, 3))
    for k in range(n):
        e[k, axes[k]] = 1.0
    n_bone = math.sqrt(bone[0] * bone[0] + bone[1] * bone[1] + bone[2] * bone[2])
    v = bone / (n_bone if n_bone > 0 else 1.0)
    a, b = e[0], e[n - 1]
    vb = v[0] * b[0] + v[1] * b[1] + v[2] * b[2]
    across = v - vb * b
    bxv = np.array([b[1] * v[2] - b[2] * v[1], b[2] * v[0] - b[0] * v[2], b[0] * v[1] - b[1] * v[0]])
    pa = across[0] * a[0] + across[1] * a[1] + across[2] * a[2]
    qa = bxv[0] * a[0] + bxv[1] * a[1] + bxv[2] * a[2]
    reach = math.hypot(pa, qa)
    phi = math.atan2(qa, pa)
    w = np.empty(3)
    t = np.empty(3)
    u = np.empty(3)
    turned = np.empty(3)
    out = np.empty(2)
    near = np.empty(2)
    for row in range(rows.size):
        f = rows[row]
        for c in range(3):
            w[c] = positions[f, child, c] - p[f, j, c]
        for c in range(3):  # the goal in the joint's axis frame: (gp^T w) @ axis
            t[c] = 0.0
        for c in range(3):
            g = gp[f, 0, c] * w[0] + gp[f, 1, c] * w[1] + gp[f, 2, c] * w[2]
            for k in range(3):
                t[k] += g * axis[c, k]
        n_goal = math.sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2])
        ok = n_goal > 0 and n_bone > 0
        for c in range(3):
            u[c] = t[c] / (n_goal if ok else 1.0)
        for k in range(n):
            near[k] = values[f, cols[k]] * scale
        if n == 1:
            out[0] = _about(a, v, u)
        else:
            ok = ok and reach > 0
            ua = u[0] * a[0] + u[1] * a[1] + u[2] * a[2]
            spread = math.acos(min(1.0, max(-1.0, ua / (reach if reach > 0 else 1.0))))
            first, second = _nearest(phi + spread, near[1]), _nearest(phi - spread, near[1])
            beta = first if abs(first - near[1]) <= abs(second - near[1]) else second
            cb, sb = math.cos(beta), math.sin(beta)
            for c in range(3):
                turned[c] = vb * b[c] + cb * across[c] + sb * bxv[c]
            out[0], out[1] = _about(a, turned, u), beta
        out[0] = _nearest(out[0], near[0])
        for k in range(n):
            ok = ok and abs(out[k] - near[k]) < max_turn
        for k in range(n):
            col = cols[k]
            raw = values[f, col]
            angle = out[k] / scale
            angle += period * np.rint((raw - angle) / period)
            if not ok:
                angle = raw
            goal[f, col] = remainder(angle - base[f, col] + half, period) - half

