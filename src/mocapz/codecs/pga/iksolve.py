"""The decoder's fast Levenberg-Marquardt IK: the iteration of :func:`mocapz.codecs.pga.ik.solve` (same
cost, damping schedule and acceptance rule), restructured for speed. The decoded coordinates agree with
the reference solver to rounding (about 1e-9 rad after 6 iterations).

What changes against the reference solver:

- every array keeps frames on its last (contiguous) axis, ``(..., F)``: numpy's element-wise loops are
  fast on long rows and slow on the short (3, 3) trailing axes of ``(F, ..., 3, 3)`` arrays, so every
  3 x 3 product is written as three broadcast multiply-adds over frames;
- forward kinematics runs over the joints on the effectors' chains only (the others move no effector);
- rotations and right Jacobians come from one closed form (``K^2 = w w^T - |w|^2 I``);
- the Jacobian is one matrix product per block of frames: with ``u_n = G_n J_r(w_n)`` (3 x 3) and the
  model's rows ``B_n`` (3 x k) of every joint ``n`` above effector ``e``, the column-wise cross products
  sum to ``J_e = (sum_n u_n B_n) x p_e + sum_n [o_n]x u_n B_n``; both sums are one GEMM per tree segment
  (joints moving the same effectors) of its rows ``B^T`` ``(k, 3n)`` against its stacked ``u_n`` and
  ``[o_n]x u_n`` ``(3n, 6F)``, added to the sums of the segment's effectors;
- the damped normal equations (symmetric positive definite) are solved by Gaussian elimination
  vectorised over frames, not by one LAPACK call per frame;
- without the temporal regulariser frames are independent and are solved in blocks of :data:`BLOCK`
  frames that fit the cache.
"""

from __future__ import annotations

import numpy as np

from mocapz.codecs.pga import ik, ikjit
from mocapz.codecs.pga.ik import IKProblem
from mocapz.codecs.pga.model import PGAModel

BLOCK = 512  # frames per block when frames are independent (lam_temporal == 0)
ACCEPT = ik.ACCEPT
_CROSS = ((1, 2), (2, 0), (0, 1))  # (c1, c2) of component c of a cross product


def rodrigues(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations ``exp(w)`` and right Jacobians ``J_r(w)``, both ``(m, 3, 3, F)``, of rotation vectors
    ``w`` ``(m, 3, F)`` (radians; frames last)."""
    th2 = w[:, 0] ** 2 + w[:, 1] ** 2 + w[:, 2] ** 2  # (m, F)
    th = np.sqrt(th2)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    s, c = np.sin(ths), np.cos(ths)
    a = np.where(small, 1.0 - th2 / 6.0, s / ths)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - c) / (ths * ths))
    cc = np.where(small, 1.0 / 6.0 - th2 / 120.0, (ths - s) / (ths**3))
    k2 = w[:, :, None] * w[:, None, :]  # w w^T, then K^2 = w w^T - th2 I
    for i in range(3):
        k2[:, i, i] -= th2
    r = b[:, None, None] * k2
    jr = cc[:, None, None] * k2
    for i in range(3):
        r[:, i, i] += 1.0
        jr[:, i, i] += 1.0
    for i, j, sign in ((0, 1, -1.0), (0, 2, 1.0), (1, 2, -1.0)):
        comp = w[:, 3 - i - j] * sign  # K[i, j]; K[j, i] = -K[i, j]
        r[:, i, j] += a * comp
        r[:, j, i] -= a * comp
        jr[:, i, j] -= b * comp
        jr[:, j, i] += b * comp
    return r, jr


def _mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Products ``a @ b`` of 3 x 3 matrices with frames last: ``(..., 3, 3, F)`` or ``(..., 3, 3, 1)``."""
    return a[..., :, 0, None, :] * b[..., None, 0, :, :] + a[..., :, 1, None, :] * b[..., None, 1, :, :] \
        + a[..., :, 2, None, :] * b[..., None, 2, :, :]


def pose(model: PGAModel, x: np.ndarray, frames: int | None = None) -> np.ndarray:
    """:meth:`PGAModel.pose` with frames last inside: rotations ``(F, n, 3, 3)`` of coordinates ``(F, k)``;
    ``frames``: the clip's length, which picks the compiled or the NumPy path (:func:`ikjit.kernels`; None: F)."""
    jit = ikjit.kernels(x.shape[0] if frames is None else frames)
    if jit is not None:
        out = np.empty((x.shape[0], model.mean.shape[0], 3, 3))
        jit["pose"](np.ascontiguousarray(x, dtype=np.float64), np.ascontiguousarray(model.basis.T, dtype=np.float64),
                    np.ascontiguousarray(model.mean, dtype=np.float64), out)
        return out
    w = (model.basis @ x.T).reshape(-1, 3, x.shape[0])
    return _mul(model.mean[..., None], rodrigues(w)[0]).transpose(3, 0, 1, 2)


class FastIK:
    """The parts of an :class:`IKProblem` the fast solver precomputes (joint chains, model rows per tree segment)."""

    def __init__(self, problem: IKProblem) -> None:
        sk, model = problem.skeleton, problem.model
        n_j = sk.n_joints
        self.problem = problem
        carriers = [int(e) if e < n_j else int(sk.point_parents[e]) for e in problem.effectors]
        chains: list[list[int]] = []
        for j in carriers:
            chain = []
            while j >= 0:
                chain.append(j)
                j = int(sk.parents[j])
            chains.append(chain[::-1])
        depth = {j: d for chain in chains for d, j in enumerate(chain)}
        self.order = sorted(depth, key=lambda j: (depth[j], j))  # parents before children
        index = {j: i for i, j in enumerate(self.order)}
        self.parent = [index.get(int(sk.parents[j]), -1) for j in self.order]
        self.carrier = np.array([index[j] for j in carriers], dtype=np.int64)
        slot = problem._slot
        # model joints on some chain, grouped by the set of effectors they move (a tree segment: legs, spine,
        # arms...), so that each group's rows are one slice of the Jacobian's stacked products
        e = len(carriers)
        moves = {j: tuple(a for a, chain in enumerate(chains) if j in chain) for j in self.order if slot[j] >= 0}
        keys = sorted(set(moves.values()))
        moving = sorted(moves, key=lambda j: (keys.index(moves[j]), index[j]))
        self.m_place = np.array([index[j] for j in moving], dtype=np.int64)
        self.slot_of = {index[j]: i for i, j in enumerate(moving)}
        k = model.k
        rows = model.basis.reshape(-1, 3, k)[np.array([slot[j] for j in moving], dtype=np.int64)]  # (m, 3, k)
        self.basis = np.ascontiguousarray(rows.reshape(-1, k))  # (3m, k): x -> w of the moving joints
        self.mean = model.mean[[slot[j] for j in moving]][..., None]  # (m, 3, 3, 1)
        self.groups: list[tuple[int, int, np.ndarray, tuple[int, ...]]] = []  # (first, stop, rows^T (k, 3n), effectors)
        for key in keys:
            first = next(i for i, j in enumerate(moving) if moves[j] == key)
            stop = first + sum(moves[j] == key for j in moving)
            self.groups.append((first, stop, np.ascontiguousarray(rows[first:stop].reshape(-1, k).T), key))
        self.n_eff = e
        self.end_off = np.zeros((e, 3))
        for a, eff in enumerate(problem.effectors):
            if eff >= n_j:
                self.end_off[a] = sk.end_sites[int(eff) - n_j][1]
        self.rest = [np.asarray(problem.rest_rot[j], dtype=np.float64)[..., None] for j in self.order]

    def forward(self, x: np.ndarray, trans: np.ndarray) -> tuple[np.ndarray, ...]:
        """Effector positions ``(e, 3, F)`` of coordinates ``x`` ``(k, F)`` with local translations ``trans``
        ``(J, 3, F)`` or ``(J, 3)``, and what the Jacobian needs: global rotations ``(N, 3, 3, F)`` and
        origins ``(N, 3, F)`` of the N chain joints, right Jacobians ``(m, 3, 3, F)`` (frames last)."""
        f = x.shape[1]
        w = (self.basis @ x).reshape(-1, 3, f)
        r, jr = rodrigues(w)
        local = _mul(self.mean, r)  # (m, 3, 3, F)
        n = len(self.order)
        g = np.empty((n, 3, 3, f))
        o = np.empty((n, 3, f))
        for i, j in enumerate(self.order):
            p = self.parent[i]
            s = self.slot_of.get(i, -1)
            loc = local[s] if s >= 0 else self.rest[i]
            if p < 0:
                g[i] = loc
                o[i] = 0.0
                continue
            gp = g[p]
            g[i] = _mul(gp, loc)
            t = trans[j]
            o[i] = o[p] + gp[:, 0] * t[0] + gp[:, 1] * t[1] + gp[:, 2] * t[2]
        gc, off = g[self.carrier], self.end_off[:, :, None]
        pos = o[self.carrier] + gc[:, :, 0] * off[:, None, 0] + gc[:, :, 1] * off[:, None, 1] \
            + gc[:, :, 2] * off[:, None, 2]
        return pos, g, o, jr

    def jacobian(self, pos: np.ndarray, g: np.ndarray, o: np.ndarray, jr: np.ndarray) -> np.ndarray:
        """Jacobian ``(e*3, k, F)`` of the effector positions w.r.t. the coordinates (row = effector*3 + axis)."""
        e, _, f = pos.shape
        m = self.m_place.size
        gm, om = g[self.m_place], o[self.m_place]
        uv = np.empty((m, 3, 2, 3, f))  # (joint, column c of u, [u | [o]x u], row, F)
        ut = uv[:, :, 0]
        ut[...] = jr[:, 0, :, None] * gm[:, None, :, 0] + jr[:, 1, :, None] * gm[:, None, :, 1] \
            + jr[:, 2, :, None] * gm[:, None, :, 2]  # ut[n, c, r] = (G_n J_r)[r, c]
        for r, (r1, r2) in enumerate(_CROSS):
            uv[:, :, 1, r] = om[:, None, r1] * ut[:, :, r2] - om[:, None, r2] * ut[:, :, r1]
        k = self.basis.shape[1]
        sums = np.zeros((e, k, 2, 3, f))
        flat = sums.reshape(e, k, 6 * f)
        for first, stop, rows_t, effs in self.groups:
            part = rows_t @ uv[first:stop].reshape(3 * (stop - first), 6 * f)  # (k, 6F)
            for a in effs:
                flat[a] += part
        big_u, big_v = sums[:, :, 0], sums[:, :, 1]  # (e, k, 3, F)
        jac = np.empty((e, 3, big_u.shape[1], f))
        for c, (c1, c2) in enumerate(_CROSS):
            jac[:, c] = big_u[:, :, c1] * pos[:, None, c2] - big_u[:, :, c2] * pos[:, None, c1] + big_v[:, :, c]
        return jac.reshape(3 * e, -1, f)


def spd_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solutions ``(k, F)`` of symmetric positive definite systems ``a`` ``(k, k, F)``, ``b`` ``(k, F)``
    (frames last), by Gaussian elimination without pivoting. ``a`` and ``b`` are overwritten; a frame whose
    system is singular gets non-finite values."""
    k = a.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        for p in range(k - 1):
            fac = a[p + 1 :, p] / a[p, p]
            a[p + 1 :, p + 1 :] -= fac[:, None] * a[p, None, p + 1 :]
            b[p + 1 :] -= fac * b[p]
        x = np.empty_like(b)
        for p in range(k - 1, -1, -1):
            x[p] = (b[p] - (a[p, p + 1 :] * x[p + 1 :]).sum(axis=0)) / a[p, p]
    return x


def solve_fast(problem: IKProblem, targets: np.ndarray, x0: np.ndarray, *, x_prior: np.ndarray | None = None,
               lam_temporal: float = 1e-3, lam_prior: float = 0.0, iterations: int = 12,
               frames: int | None = None) -> np.ndarray:
    """:func:`mocapz.codecs.pga.ik.solve`, faster (same arguments; the same result to rounding): ``(F, k)``
    coordinates (radians) for effector targets ``(F, e, 3)`` in the root frame (file units). ``frames``: the
    clip's length, which picks the compiled or the NumPy path (:func:`ikjit.kernels`; None: F)."""
    fast = FastIK(problem)
    jit = ikjit.kernels(targets.shape[0] if frames is None else frames)
    if jit is not None and lam_temporal <= 0:
        return _solve_jit(jit, fast, targets, x0, x_prior, lam_prior, iterations)
    x = np.array(x0, dtype=np.float64).T.copy()  # (k, F)
    f = x.shape[1]
    trans = problem.trans.transpose(1, 2, 0) if problem.trans.ndim == 3 else problem.trans  # (J, 3, F)
    tgt = targets.transpose(1, 2, 0).reshape(-1, f)  # (e*3, F)
    prior = None if x_prior is None or lam_prior <= 0 else np.asarray(x_prior, dtype=np.float64).T
    bounds = [(0, f)] if lam_temporal > 0 else [(a, min(f, a + BLOCK)) for a in range(0, f, BLOCK)]
    for a, b in bounds:
        tr = trans[..., a:b] if trans.ndim == 3 else trans
        x[:, a:b] = _solve_block(fast, tr, tgt[:, a:b], x[:, a:b], None if prior is None else prior[:, a:b],
                                 lam_temporal, lam_prior, iterations)
    return x.T.copy()


def _solve_jit(jit: dict, fast: FastIK, targets: np.ndarray, x0: np.ndarray, x_prior: np.ndarray | None,
               lam_prior: float, iterations: int) -> np.ndarray:
    """:func:`solve_fast` without the temporal regulariser, by the compiled kernel (frames independent)."""
    problem = fast.problem
    x = np.array(x0, dtype=np.float64, order="C")
    f, k = x.shape
    use_prior = x_prior is not None and lam_prior > 0
    # every argument C-contiguous float64 / int64, whatever the caller passes: one compiled signature
    prior = np.ascontiguousarray(x_prior, dtype=np.float64) if use_prior else np.zeros((f, k))
    per_frame = problem.trans.ndim == 3
    trans = np.ascontiguousarray(problem.trans if per_frame else problem.trans[None], dtype=np.float64)
    order = np.asarray(fast.order, dtype=np.int64)
    mslot = np.array([fast.slot_of.get(i, -1) for i in range(order.size)], dtype=np.int64)
    moves = np.zeros((fast.m_place.size, fast.n_eff), dtype=np.bool_)
    for first, stop, _, effs in fast.groups:
        moves[first:stop, list(effs)] = True
    rest = np.ascontiguousarray(np.stack([r[..., 0] for r in fast.rest]) if fast.rest else np.zeros((0, 3, 3)),
                                dtype=np.float64)
    jit["solve_frames"](x, np.ascontiguousarray(targets, dtype=np.float64).reshape(f, -1), prior, trans,
                        bool(per_frame), fast.basis, np.ascontiguousarray(fast.basis.T),
                        np.ascontiguousarray(fast.mean[..., 0]), order,
                        np.asarray(fast.parent, dtype=np.int64), mslot, rest, fast.carrier, fast.end_off,
                        fast.m_place, moves, 1.0 / float(problem.scale) ** 2, float(lam_prior), bool(use_prior),
                        int(iterations))
    return x


def _solve_block(fast: FastIK, trans: np.ndarray, tgt: np.ndarray, x: np.ndarray, prior: np.ndarray | None,
                 lam_temporal: float, lam_prior: float, iterations: int) -> np.ndarray:
    """LM on one block: coordinates ``x`` ``(k, F)``, targets ``(e*3, F)``, frames last (all frames when
    ``lam_temporal > 0``: the regulariser ties neighbours)."""
    k, f = x.shape
    inv_l2 = 1.0 / fast.problem.scale**2
    mu = np.full(f, 1e-3)
    diag = np.arange(k)

    def cost(xc: np.ndarray, pos: np.ndarray, xprev: np.ndarray, xnext: np.ndarray) -> np.ndarray:
        c = ((pos.reshape(-1, f) - tgt) ** 2).sum(axis=0) * inv_l2
        if lam_temporal > 0:
            c = c + lam_temporal * (((xc - xprev) ** 2).sum(0) + ((xc - xnext) ** 2).sum(0))
        if prior is not None:
            c = c + lam_prior * ((xc - prior) ** 2).sum(0)
        return c

    state = fast.forward(x, trans)
    xprev = xnext = x
    for _ in range(iterations):
        if lam_temporal > 0:
            xprev = np.concatenate([x[:, :1], x[:, :-1]], axis=1)
            xnext = np.concatenate([x[:, 1:], x[:, -1:]], axis=1)
        jac = fast.jacobian(*state)
        r = tgt - state[0].reshape(-1, f)
        a = np.einsum("rif,rjf->ijf", jac, jac) * inv_l2
        b = np.einsum("rif,rf->if", jac, r) * inv_l2
        extra = 2 * lam_temporal + (lam_prior if prior is not None else 0.0)
        a[diag, diag] += extra
        if lam_temporal > 0:
            b += lam_temporal * ((xprev - x) + (xnext - x))
        if prior is not None:
            b += lam_prior * (prior - x)
        a[diag, diag] += mu * np.maximum(a[diag, diag], 1e-12)
        step = spd_solve(a, b)
        step = np.where(np.isfinite(step), step, 0.0)
        x_new = x + step
        new = fast.forward(x_new, trans)
        ok = cost(x_new, new[0], xprev, xnext)
        ok = np.isfinite(ok) & (ok <= ACCEPT * cost(x, state[0], xprev, xnext))
        x = np.where(ok, x_new, x)
        if ok.all():
            state = new
        elif ok.any():
            for old, nw in zip(state, new, strict=True):
                old[..., ok] = nw[..., ok]
        mu = np.where(ok, np.maximum(mu / 3.0, 1e-7), np.minimum(mu * 4.0, 1e6))
    return x
