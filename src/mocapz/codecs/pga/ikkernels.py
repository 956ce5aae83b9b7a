"""The compiled (numba) kernels of :mod:`mocapz.codecs.pga.ikjit` (imported only when numba is installed;
module-level functions, so that numba's on-disk cache keeps them across processes)."""

# ruff: noqa: ANN001, ANN202
from __future__ import annotations

import math

import numpy as np
from numba import njit

from mocapz.codecs.pga.ik import ACCEPT

LANES = 32  # frames solved side by side (the innermost, vectorised axis of the compiled IK's arrays)

jit = njit(cache=True, nogil=True, error_model="numpy")


@jit
def rodrigues1(w0: float, w1: float, w2: float, r: np.ndarray) -> None:
    """``exp(w)`` into ``r`` (3, 3) (the closed form of :func:`mocapz.codecs.pga.iksolve.rodrigues`)."""
    th2 = w0 * w0 + w1 * w1 + w2 * w2
    th = math.sqrt(th2)
    if th < 1e-4:
        a = 1.0 - th2 / 6.0
        b = 0.5 - th2 / 24.0
    else:
        a = math.sin(th) / th
        b = (1.0 - math.cos(th)) / (th * th)
    w = (w0, w1, w2)
    for i in range(3):
        for j in range(3):
            r[i, j] = b * (w[i] * w[j] - th2) + 1.0 if i == j else b * (w[i] * w[j])
    # K = [[0, -w2, w1], [w2, 0, -w0], [-w1, w0, 0]]; r += a K
    r[0, 1] -= a * w2
    r[1, 0] += a * w2
    r[0, 2] += a * w1
    r[2, 0] -= a * w1
    r[1, 2] -= a * w0
    r[2, 1] += a * w0

@jit
def rodrigues(w0: np.ndarray, w1: np.ndarray, w2: np.ndarray, r: np.ndarray, jr: np.ndarray, sc: np.ndarray) -> None:
    """``exp(w)`` into ``r`` and ``J_r(w)`` into ``jr`` (3, 3, L) for every lane: :func:`rodrigues1`'s float
    operations, only ``sin`` and ``cos`` lane by lane, the rest vectorised over lanes; ``sc`` (7, L) scratch."""
    nq = w0.size
    th2, th, s, c, a, b, cc = sc[0], sc[1], sc[2], sc[3], sc[4], sc[5], sc[6]
    for q in range(nq):
        th2[q] = w0[q] * w0[q] + w1[q] * w1[q] + w2[q] * w2[q]
        th[q] = math.sqrt(th2[q])
    for q in range(nq):
        s[q], c[q] = math.sin(th[q]), math.cos(th[q])
    for q in range(nq):
        t2, t = th2[q], th[q]
        a[q] = 1.0 - t2 / 6.0 if t < 1e-4 else s[q] / t
        b[q] = 0.5 - t2 / 24.0 if t < 1e-4 else (1.0 - c[q]) / (t * t)
        cc[q] = 1.0 / 6.0 - t2 / 120.0 if t < 1e-4 else (t - s[q]) / (t**3)
    for i in range(3):
        wi = w0 if i == 0 else (w1 if i == 1 else w2)
        for j in range(3):
            wj = w0 if j == 0 else (w1 if j == 1 else w2)
            wk = w0 if i + j == 3 else (w1 if i + j == 2 else w2)  # K[i, j] = +-w_k, K = hat(w)
            ri, ji = r[i, j], jr[i, j]
            if i == j:
                for q in range(nq):
                    k2 = wi[q] * wj[q] - th2[q]
                    ri[q], ji[q] = b[q] * k2 + 1.0, cc[q] * k2 + 1.0
            elif (j - i) % 3 == 2:  # K[i, j] = +w_k: r += a K, jr -= b K
                for q in range(nq):
                    k2 = wi[q] * wj[q]
                    ri[q], ji[q] = b[q] * k2 + a[q] * wk[q], cc[q] * k2 - b[q] * wk[q]
            else:  # K[i, j] = -w_k
                for q in range(nq):
                    k2 = wi[q] * wj[q]
                    ri[q], ji[q] = b[q] * k2 - a[q] * wk[q], cc[q] * k2 + b[q] * wk[q]


@jit
def mul33(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@jit
def mul33_lanes(x: np.ndarray, y: np.ndarray, out: np.ndarray, nq: int) -> None:
    """``out[:, :, q] = x[:, :, q] @ y[:, :, q]`` for the first ``nq`` lanes (3 x 3 matrices)."""
    for a in range(3):
        for b in range(3):
            for q in range(nq):
                out[a, b, q] = x[a, 0, q] * y[0, b, q] + x[a, 1, q] * y[1, b, q] + x[a, 2, q] * y[2, b, q]


@jit
def forward(x, basis_t, mean, order, parent, mslot, rest, trans, carrier, end_off,  # noqa: ANN001
            w, r, jr, local, g, o, pos, sc):
    """FK of a block of ``LANES`` frames (frames on the last axis of every array): effector positions
    ``pos`` (e, 3, L), chain rotations ``g`` (N, 3, 3, L) and origins ``o`` (N, 3, L), right Jacobians
    ``jr`` (m, 3, 3, L) of the moving joints, for coordinates ``x`` (k, L); ``sc`` (7, L) scratch."""
    k, m3 = basis_t.shape
    nq = x.shape[1]  # LANES (a run-time count: numba vectorises such loops, not fixed-count ones)
    w[:] = 0.0
    for c in range(k):
        for i in range(m3):
            bc = basis_t[c, i]
            for q in range(nq):
                w[i, q] += bc * x[c, q]
    for n in range(m3 // 3):
        rodrigues(w[3 * n], w[3 * n + 1], w[3 * n + 2], r, jr[n], sc)
        mn = mean[n]
        for a in range(3):
            for b in range(3):
                for q in range(nq):
                    local[n, a, b, q] = mn[a, 0] * r[0, b, q] + mn[a, 1] * r[1, b, q] + mn[a, 2] * r[2, b, q]
    for i in range(order.size):
        s = mslot[i]
        p = parent[i]
        loc = local[s] if s >= 0 else rest[i]
        if p < 0:
            g[i] = loc
            o[i] = 0.0
            continue
        gp = g[p]
        mul33_lanes(gp, loc, g[i], nq)
        j = order[i]
        for a in range(3):
            for q in range(nq):
                o[i, a, q] = o[p, a, q] + gp[a, 0, q] * trans[j, 0, q] + gp[a, 1, q] * trans[j, 1, q] \
                    + gp[a, 2, q] * trans[j, 2, q]
    for e in range(carrier.size):
        c = carrier[e]
        for a in range(3):
            for q in range(nq):
                pos[e, a, q] = o[c, a, q] + g[c, a, 0, q] * end_off[e, 0] + g[c, a, 1, q] * end_off[e, 1] \
                    + g[c, a, 2, q] * end_off[e, 2]

@jit
def cost(x, pos, tgt, prior, lam_prior, use_prior, inv_l2, out):  # noqa: ANN001
    """The LM cost of every lane into ``out`` (L,)."""
    e = pos.shape[0]
    nq = out.size
    out[:] = 0.0
    for a in range(e):
        for b in range(3):
            for q in range(nq):
                d = pos[a, b, q] - tgt[3 * a + b, q]
                out[q] += d * d
    for q in range(nq):
        out[q] *= inv_l2
    if use_prior:
        k = x.shape[0]
        acc = np.zeros(nq)
        for c in range(k):
            for q in range(nq):
                d = x[c, q] - prior[c, q]
                acc[q] += d * d
        for q in range(nq):
            out[q] += lam_prior * acc[q]

@jit
def solve_block(x, tf, pf, tr, basis, basis_t, mean, order, parent, mslot, rest, carrier,  # noqa: ANN001
                end_off, m_place, moves, inv_l2, lam_prior, use_prior, iterations, ws):
    """LM on one block of ``LANES`` frames: ``x`` (k, L) in place, targets ``tf`` (3e, L), prior ``pf``
    (k, L), translations ``tr`` (J, 3, L); ``ws`` the work arrays."""
    (w, r, u, v, jac, am, bv, step, xn, mu, c_old, c_new, ok, cur, new, sc) = ws
    k, nq = x.shape
    m = m_place.size
    e = carrier.size
    jr_c, loc_c, g_c, o_c, pos_c = cur
    forward(x, basis_t, mean, order, parent, mslot, rest, tr, carrier, end_off, w, r, jr_c, loc_c, g_c,
            o_c, pos_c, sc)
    mu[:] = 1e-3
    cost(x, pos_c, tf, pf, lam_prior, use_prior, inv_l2, c_old)
    for _ in range(iterations):
        jr_c, loc_c, g_c, o_c, pos_c = cur
        # Jacobian (3e, k, L): columns (G_n J_r(w_n) B_n) crossed with p_e - o_n
        jac[:] = 0.0
        for n in range(m):
            i = m_place[n]
            gi = g_c[i]
            jn = jr_c[n]
            mul33_lanes(gi, jn, u, nq)
            for a in range(3):
                for c in range(k):
                    b0, b1, b2 = basis[3 * n, c], basis[3 * n + 1, c], basis[3 * n + 2, c]
                    for q in range(nq):
                        v[a, c, q] = u[a, 0, q] * b0 + u[a, 1, q] * b1 + u[a, 2, q] * b2
            for ef in range(e):
                if not moves[n, ef]:
                    continue
                for q in range(nq):
                    r[0, 0, q] = pos_c[ef, 0, q] - o_c[i, 0, q]
                    r[0, 1, q] = pos_c[ef, 1, q] - o_c[i, 1, q]
                    r[0, 2, q] = pos_c[ef, 2, q] - o_c[i, 2, q]
                d = r[0]
                for c in range(k):
                    for q in range(nq):
                        jac[3 * ef, c, q] += v[1, c, q] * d[2, q] - v[2, c, q] * d[1, q]
                        jac[3 * ef + 1, c, q] += v[2, c, q] * d[0, q] - v[0, c, q] * d[2, q]
                        jac[3 * ef + 2, c, q] += v[0, c, q] * d[1, q] - v[1, c, q] * d[0, q]
        # damped normal equations (sums over the rows in order; one row of ``am`` at a time, kept in cache)
        am[:] = 0.0
        bv[:] = 0.0
        for rr in range(3 * e):
            for q in range(nq):
                step[0, q] = tf[rr, q] - pos_c[rr // 3, rr % 3, q]
            jr_row = jac[rr]
            for i in range(k):
                for q in range(nq):
                    bv[i, q] += jr_row[i, q] * step[0, q]
        acc = xn[0]
        for i in range(k):
            for j in range(i, k):
                for q in range(nq):
                    acc[q] = 0.0
                for rr in range(3 * e):
                    for q in range(nq):
                        acc[q] += jac[rr, i, q] * jac[rr, j, q]
                for q in range(nq):
                    am[i, j, q] = acc[q]
        for i in range(k):
            for q in range(nq):
                bv[i, q] *= inv_l2
            for j in range(i, k):
                for q in range(nq):
                    am[i, j, q] *= inv_l2
                    am[j, i, q] = am[i, j, q]
        for i in range(k):
            for q in range(nq):
                if use_prior:
                    am[i, i, q] += lam_prior
                    bv[i, q] += lam_prior * (pf[i, q] - x[i, q])
                am[i, i, q] += mu[q] * max(am[i, i, q], 1e-12)
        # Gaussian elimination without pivoting (symmetric positive definite)
        for p in range(k - 1):
            for i in range(p + 1, k):
                for q in range(nq):
                    u[0, 0, q] = am[i, p, q] / am[p, p, q]
                for j in range(p + 1, k):
                    for q in range(nq):
                        am[i, j, q] -= u[0, 0, q] * am[p, j, q]
                for q in range(nq):
                    bv[i, q] -= u[0, 0, q] * bv[p, q]
        for p in range(k - 1, -1, -1):
            for q in range(nq):
                u[0, 0, q] = 0.0
            for j in range(p + 1, k):
                for q in range(nq):
                    u[0, 0, q] += am[p, j, q] * step[j, q]
            for q in range(nq):
                step[p, q] = (bv[p, q] - u[0, 0, q]) / am[p, p, q]
        for i in range(k):
            for q in range(nq):
                sq = step[i, q]
                xn[i, q] = x[i, q] + (sq if math.isfinite(sq) else 0.0)
        jr_n, loc_n, g_n, o_n, pos_n = new
        forward(xn, basis_t, mean, order, parent, mslot, rest, tr, carrier, end_off, w, r, jr_n, loc_n,
                g_n, o_n, pos_n, sc)
        cost(xn, pos_n, tf, pf, lam_prior, use_prior, inv_l2, c_new)
        n_ok = 0
        for q in range(nq):
            ok[q] = math.isfinite(c_new[q]) and c_new[q] <= ACCEPT * c_old[q]
            n_ok += ok[q]
            if ok[q]:
                c_old[q] = c_new[q]
                mu[q] = max(mu[q] / 3.0, 1e-7)
            else:
                mu[q] = min(mu[q] * 4.0, 1e6)
        if n_ok == nq:
            x[:] = xn
            cur, new = new, cur
        elif n_ok:
            for q in range(nq):
                if ok[q]:
                    x[:, q] = xn[:, q]
                    jr_c[..., q] = jr_n[..., q]
                    g_c[..., q] = g_n[..., q]
                    o_c[..., q] = o_n[..., q]
                    pos_c[..., q] = pos_n[..., q]

@jit
def solve_frames(x, tgt, prior, trans, per_frame, basis, basis_t, mean, order, parent, mslot, rest, carrier,  # noqa: ANN001
                 end_off, m_place, moves, inv_l2, lam_prior, use_prior, iterations):
    """LM on every frame of ``x`` (F, k) in place, blocks of ``LANES`` frames (targets ``tgt`` (F, 3e),
    prior (F, k), translations ``trans`` (F or 1, J, 3))."""
    f, k = x.shape
    m = m_place.size
    nn = order.size
    e = carrier.size
    n_j = trans.shape[1]
    ws = (np.empty((3 * m, LANES)), np.empty((3, 3, LANES)), np.empty((3, 3, LANES)), np.empty((3, k, LANES)),
          np.empty((3 * e, k, LANES)), np.empty((k, k, LANES)), np.empty((k, LANES)), np.empty((k, LANES)),
          np.empty((k, LANES)), np.empty(LANES), np.empty(LANES), np.empty(LANES), np.zeros(LANES, np.bool_),
          (np.empty((m, 3, 3, LANES)), np.empty((m, 3, 3, LANES)), np.empty((nn, 3, 3, LANES)),
           np.empty((nn, 3, LANES)), np.empty((e, 3, LANES))),
          (np.empty((m, 3, 3, LANES)), np.empty((m, 3, 3, LANES)), np.empty((nn, 3, 3, LANES)),
           np.empty((nn, 3, LANES)), np.empty((e, 3, LANES))), np.empty((7, LANES)))
    rest_l = np.empty((nn, 3, 3, LANES))
    for i in range(nn):
        for a in range(3):
            for b in range(3):
                rest_l[i, a, b, :] = rest[i, a, b]
    xb = np.empty((k, LANES))
    tb = np.empty((3 * e, LANES))
    pb = np.empty((k, LANES))
    trb = np.empty((n_j, 3, LANES))
    if not per_frame:
        for j in range(n_j):
            for a in range(3):
                trb[j, a, :] = trans[0, j, a]
    for f0 in range(0, f, LANES):
        for q in range(LANES):
            fi = min(f0 + q, f - 1)  # the last block repeats the last frame
            xb[:, q] = x[fi]
            tb[:, q] = tgt[fi]
            pb[:, q] = prior[fi]
            if per_frame:
                trb[:, :, q] = trans[fi]
        solve_block(xb, tb, pb, trb, basis, basis_t, mean, order, parent, mslot, rest_l, carrier, end_off,
                    m_place, moves, inv_l2, lam_prior, use_prior, iterations, ws)
        for q in range(min(LANES, f - f0)):
            x[f0 + q] = xb[:, q]

@jit
def coords_to_vectors(xf: np.ndarray, basis_t: np.ndarray, w: np.ndarray) -> None:
    """``w = xf @ basis_t``: a frame's rotation vectors (3n,) from its coordinates (k,), summed in order."""
    w[:] = 0.0
    for c in range(xf.size):
        xc = xf[c]
        for i in range(w.size):
            w[i] += basis_t[c, i] * xc


@jit
def pose(x, basis_t, mean, out):  # noqa: ANN001
    """Local rotations ``out`` (F, n, 3, 3) of the model's joints for coordinates ``x`` (F, k)."""
    f, k = x.shape
    n3 = basis_t.shape[1]
    w = np.empty(n3)
    r = np.empty((3, 3))
    for fi in range(f):
        coords_to_vectors(x[fi], basis_t, w)
        for n in range(n3 // 3):
            rodrigues1(w[3 * n], w[3 * n + 1], w[3 * n + 2], r)
            mul33(mean[n], r, out[fi, n])

@jit
def euler_channels(x, basis_t, mean, root_rot, src, ijk, sign, cols, axes, has_axis, scale, out):  # noqa: ANN001
    """Euler channels of the decoded pose, straight into ``out`` (F, C): per rotating joint ``q`` its
    rotation (``src[q]``: the root's ``root_rot`` (F, 3, 3) when -1, else model slot ``src[q]`` of
    coordinates ``x`` (F, k)), turned into the joint's axis frame when ``has_axis[q]``, as the angles of
    the intrinsic sequence ``ijk[q]`` (parity ``sign[q]``; :func:`mocapz.codecs.pga.channels.euler_angles`)
    times ``scale``, written to columns ``cols[q]`` (-1: not a channel). Returns the number of non-finite
    rotation entries (damaged streams)."""
    f, k = x.shape
    n3 = basis_t.shape[1]
    w = np.empty(n3)
    r = np.empty((3, 3))
    rm = np.empty((3, 3))
    tmp = np.empty((3, 3))
    ang = np.empty(3)
    bad = 0
    for fi in range(f):
        coords_to_vectors(x[fi], basis_t, w)
        for q in range(src.size):
            sq = src[q]
            if sq < 0:
                rm[:, :] = root_rot[fi]
            else:
                rodrigues1(w[3 * sq], w[3 * sq + 1], w[3 * sq + 2], r)
                mul33(mean[sq], r, rm)
            for a in range(3):
                for b in range(3):
                    if not math.isfinite(rm[a, b]):
                        bad += 1
            if has_axis[q]:
                ax = axes[q]
                for a in range(3):
                    for b in range(3):
                        tmp[a, b] = ax[0, a] * rm[0, b] + ax[1, a] * rm[1, b] + ax[2, a] * rm[2, b]
                mul33(tmp, ax, rm)
            i, j, kk = ijk[q, 0], ijk[q, 1], ijk[q, 2]
            sg = sign[q]
            cb = math.hypot(rm[i, i], rm[i, j])
            ang[1] = math.atan2(sg * rm[i, kk], cb)
            if cb < 1e-9:
                ang[0] = math.atan2(sg * rm[kk, j], rm[j, j])
                ang[2] = 0.0
            else:
                ang[0] = math.atan2(-sg * rm[j, kk], rm[kk, kk])
                ang[2] = math.atan2(-sg * rm[i, j], rm[i, i])
            for t in range(3):
                if cols[q, t] >= 0:
                    out[fi, cols[q, t]] = ang[t] * scale if scale != 1.0 else ang[t]
    return bad
