"""PGA-based inverse kinematics, batched over all frames.

``f = FK o h`` maps geodesic coordinates ``x`` (k,) to the end-effector positions in the root frame.
Its Jacobian is analytic: ``dh/dx_j = v_j`` in the tangent space (through the right Jacobian of exp),
then the chain rule through forward kinematics: a rotation ``delta`` of joint ``i`` in its local frame
moves a point ``p`` below it by ``(G_i delta) x (p - o_i)``.

Levenberg-Marquardt minimises, for every frame at once,
``||f(x) - y||^2 / L^2 + lambda_t ||x - x_prev||^2 + lambda_p ||x - x_prior||^2``
where ``L`` is the skeleton's size (so lambda is unit-free), ``x_prev`` is the current solution of the
previous frame (the paper's temporal regulariser, iterated to a consistent fixed point over the batch)
and ``x_prior`` optional coded coordinates used as warm start.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapz.codecs.pga import so3
from mocapz.codecs.pga.joints import column_joints, position_columns, skeleton_scale
from mocapz.codecs.pga.model import PGAModel
from mocapz.model.skeleton import Skeleton

# a step is taken when it lowers the cost by more than rounding: at convergence the costs of the old and new
# coordinates differ by rounding only, and ``<=`` would then take or refuse the step by the last bit (unlike
# solvers that add up in another order: the compiled kernels); this way every solver stops there alike
ACCEPT = 1.0 - 1e-12


@dataclass
class IKProblem:
    """The fixed parts of the IK: skeleton, model, effectors and the non-modelled local transforms.

    Attributes:
        skeleton: the skeleton.
        model: the PGA pose model (its joints are the inner rotating joints).
        effectors: FK point indices (joints or end sites) constrained by the IK, ``(e,)``.
        rest_rot: local rotations ``(J, 3, 3)`` of joints the model does not drive (root = identity).
        trans: local translations ``(F, J, 3)`` or ``(J, 3)``; the root's is ignored (root frame).
        scale: characteristic length of the skeleton (file units), making lambda unit-free.
    """

    skeleton: Skeleton
    model: PGAModel
    effectors: np.ndarray
    rest_rot: np.ndarray
    trans: np.ndarray
    scale: float

    def __post_init__(self) -> None:
        sk = self.skeleton
        n_j = sk.n_joints
        self._slot = np.full(n_j, -1)
        self._slot[self.model.joints] = np.arange(len(self.model.joints))
        pp = sk.point_parents
        # carrier joint of each effector (the joint whose frame holds the point) and its ancestors
        carrier = np.array([e if e < n_j else pp[e] for e in self.effectors])
        self._mask = np.zeros((len(self.effectors), len(self.model.joints)))
        for a, e in enumerate(self.effectors):
            j = int(carrier[a]) if e >= n_j else int(pp[e])
            while j >= 0:
                if self._slot[j] >= 0:
                    self._mask[a, self._slot[j]] = 1.0
                j = int(sk.parents[j])
        self._end_off = {n_j + i: np.asarray(off) for i, (_, off, _) in enumerate(sk.end_sites)}

    def forward(self, x: np.ndarray, frames: slice | np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Effector positions ``(F, e, 3)`` in the root frame, with what the Jacobian needs."""
        sk, model = self.skeleton, self.model
        f = x.shape[0]
        w = (x @ model.basis.T).reshape(f, -1, 3)
        local_model = model.mean[None] @ so3.exp(w)
        trans = self.trans if self.trans.ndim == 3 else np.broadcast_to(self.trans, (f, *self.trans.shape))
        if frames is not None and self.trans.ndim == 3:
            trans = self.trans[frames]
        g = np.empty((f, sk.n_joints, 3, 3))
        o = np.empty((f, sk.n_joints, 3))
        for j in range(sk.n_joints):
            p = sk.parents[j]
            slot = self._slot[j]
            loc = local_model[:, slot] if slot >= 0 else self.rest_rot[j]
            if p < 0:
                g[:, j] = loc if slot >= 0 else np.broadcast_to(loc, (f, 3, 3))
                o[:, j] = 0.0
            else:
                g[:, j] = g[:, p] @ loc
                o[:, j] = o[:, p] + np.einsum("fab,fb->fa", g[:, p], trans[:, j])
        pos = np.empty((f, len(self.effectors), 3))
        for a, e in enumerate(self.effectors):
            if e < sk.n_joints:
                pos[:, a] = o[:, e]
            else:
                j = int(sk.point_parents[e])
                pos[:, a] = o[:, j] + g[:, j] @ self._end_off[int(e)]
        return pos, g, o, w

    def jacobian(self, pos: np.ndarray, g: np.ndarray, o: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Analytic Jacobian ``(F, e, 3, k)`` of the effector positions w.r.t. the coordinates."""
        model = self.model
        joints = model.joints
        basis = model.basis.reshape(len(joints), 3, -1)  # (n, 3, k)
        a = g[:, joints] @ so3.right_jacobian(w) @ basis[None]  # (F, n, 3, k)
        d = pos[:, :, None, :] - o[:, None, joints, :]  # (F, e, n, 3)
        dm = d * self._mask[None, :, :, None]  # only joints above each effector move it
        # column-wise cross product a x d, summed over joints: written out per component (np.cross on
        # 5-D arrays is ten times slower)
        jac = np.empty((pos.shape[0], pos.shape[1], 3, a.shape[-1]))
        for c, (i1, i2) in enumerate(((1, 2), (2, 0), (0, 1))):
            jac[:, :, c] = dm[..., i2] @ a[:, :, i1] - dm[..., i1] @ a[:, :, i2]
        return jac


def make_problem(skeleton: Skeleton, model: PGAModel, effectors: np.ndarray, other: np.ndarray,
                 scale: float | None = None) -> IKProblem:
    """The IK set-up for FK points ``effectors`` ``(e,)``, with the non-root position channels ``(F, p)``
    (file units; as decoded, if any) as translations; ``scale``: the skeleton's :func:`.joints.skeleton_scale`,
    where the caller has it (a rate search's, made once)."""
    n = other.shape[0]
    _, other_cols = position_columns(skeleton)
    if other_cols.size:
        trans = np.broadcast_to(skeleton.offsets, (n, skeleton.n_joints, 3)).copy()
        col_joint = column_joints(skeleton)
        for i, c in enumerate(other_cols):
            trans[:, col_joint[c][0], "XYZ".index(col_joint[c][1])] = other[:, i]
    else:
        trans = skeleton.offsets
    problem = IKProblem(skeleton, model, effectors, np.broadcast_to(np.eye(3), (skeleton.n_joints, 3, 3)),
                        trans, skeleton_scale(skeleton) if scale is None else scale)
    return problem


def solve(problem: IKProblem, targets: np.ndarray, x0: np.ndarray, *, x_prior: np.ndarray | None = None,
          lam_temporal: float = 1e-3, lam_prior: float = 0.0, iterations: int = 12) -> np.ndarray:
    """Batched Levenberg-Marquardt IK.

    Args:
        problem: the fixed IK set-up.
        targets: ``(F, e, 3)`` effector positions in the root frame, file units.
        x0: ``(F, k)`` starting coordinates (warm start).
        x_prior: ``(F, k)`` coordinates to stay near (weight ``lam_prior``), or None.
        lam_temporal: weight of ``||x_t - x_{t-1}||^2``.
        iterations: LM iterations (every frame is updated in every iteration).

    Returns:
        ``(F, k)`` coordinates. Frames whose step fails keep their last good value, so the result
        is always finite.
    """
    x = np.array(x0, dtype=np.float64)
    f, k = x.shape
    inv_l2 = 1.0 / problem.scale**2
    mu = np.full(f, 1e-3)
    eye = np.eye(k)

    def cost_terms(xc: np.ndarray, pos: np.ndarray, xprev: np.ndarray, xnext: np.ndarray) -> np.ndarray:
        c = ((pos - targets) ** 2).sum(axis=(1, 2)) * inv_l2
        c = c + lam_temporal * (((xc - xprev) ** 2).sum(1) + ((xc - xnext) ** 2).sum(1))
        if x_prior is not None and lam_prior > 0:
            c = c + lam_prior * ((xc - x_prior) ** 2).sum(1)
        return c

    pos, g, o, w = problem.forward(x)
    for _ in range(iterations):
        xprev = np.concatenate([x[:1], x[:-1]])
        xnext = np.concatenate([x[1:], x[-1:]])
        jac = problem.jacobian(pos, g, o, w).reshape(f, -1, k)
        r = (targets - pos).reshape(f, -1)
        a = np.einsum("fri,frj->fij", jac, jac) * inv_l2
        b = np.einsum("fri,fr->fi", jac, r) * inv_l2
        # temporal term towards both neighbours (symmetric, so the fixed point is the smoothed solution)
        a = a + 2 * lam_temporal * eye
        b = b + lam_temporal * ((xprev - x) + (xnext - x))
        if x_prior is not None and lam_prior > 0:
            a = a + lam_prior * eye
            b = b + lam_prior * (x_prior - x)
        diag = np.einsum("fii->fi", a)
        a_damped = a + (mu[:, None] * np.maximum(diag, 1e-12))[:, :, None] * eye
        try:
            step = np.linalg.solve(a_damped, b[..., None])[..., 0]
        except np.linalg.LinAlgError:
            step = np.zeros_like(x)
        step = np.where(np.isfinite(step), step, 0.0)
        x_new = x + step
        pos_new, g_new, o_new, w_new = problem.forward(x_new)
        before = cost_terms(x, pos, xprev, xnext)
        after = cost_terms(x_new, pos_new, xprev, xnext)
        ok = np.isfinite(after) & (after <= ACCEPT * before)
        x = np.where(ok[:, None], x_new, x)
        pos = np.where(ok[:, None, None], pos_new, pos)
        g = np.where(ok[:, None, None, None], g_new, g)
        o = np.where(ok[:, None, None], o_new, o)
        w = np.where(ok[:, None, None], w_new, w)
        mu = np.where(ok, np.maximum(mu / 3.0, 1e-7), np.minimum(mu * 4.0, 1e6))
    return x
