"""Approximate Principal Geodesic Analysis of inner-joint rotations (Fletcher et al.).

A pose is the tuple of local rotations of the *inner* joints (every joint with rotation channels except
the root, whose orientation is left out as in the paper) in ``SO(3)^n``. The model is the intrinsic mean
``mu`` and ``k`` orthonormal tangent directions ``V`` (``3n x k``); geodesic coordinates ``x`` give the
pose ``h(x) = mu * exp(V x)`` joint by joint (the tangent-space form of ``mu * prod_j exp(x_j v_j)``, which
it equals to second order and which makes the reconstruction exact when all directions are kept).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapz.codecs.pga import so3


@dataclass
class PGAModel:
    """A fitted pose model.

    Attributes:
        joints: skeleton indices of the modelled (inner) joints, ``(n,)``.
        mean: intrinsic mean rotations ``(n, 3, 3)``.
        basis: principal directions ``(3n, k)``, orthonormal columns, ordered by variance.
        variance: variance along every principal direction ``(min(3n, frames),)`` (rad^2), all of them,
            for the explained-variance curve (the paper's Fig. 3).
    """

    joints: np.ndarray
    mean: np.ndarray
    basis: np.ndarray
    variance: np.ndarray

    @property
    def k(self) -> int:
        return int(self.basis.shape[1])

    def explained(self) -> np.ndarray:
        """Cumulative fraction of the variance explained by the first 1, 2, ... directions."""
        tot = float(self.variance.sum())
        return np.cumsum(self.variance) / tot if tot > 0 else np.ones_like(self.variance)

    def tangent(self, rotations: np.ndarray) -> np.ndarray:
        """Tangent vectors ``(frames, 3n)`` of poses ``(frames, n, 3, 3)`` at the mean."""
        return so3.log_between(self.mean, rotations).reshape(rotations.shape[0], -1)

    def project(self, rotations: np.ndarray) -> np.ndarray:
        """Geodesic coordinates ``(frames, k)`` of poses ``(frames, n, 3, 3)``."""
        return self.tangent(rotations) @ self.basis

    def pose(self, x: np.ndarray) -> np.ndarray:
        """Rotations ``(frames, n, 3, 3)`` of geodesic coordinates ``(frames, k)``."""
        w = (x @ self.basis.T).reshape(x.shape[0], -1, 3)
        return self.mean[None] @ so3.exp(w)

    def truncated(self, k: int) -> PGAModel:
        return PGAModel(self.joints, self.mean, self.basis[:, :k].copy(), self.variance)


def fit_pga(rotations: np.ndarray, joints: np.ndarray, k: int | None = None) -> PGAModel:
    """Fit the model to poses ``(frames, n, 3, 3)`` of the given joints; keep ``k`` directions (all if None)."""
    mean = so3.karcher_mean(rotations)
    w = so3.log_between(mean, rotations).reshape(rotations.shape[0], -1)
    # w is centred at the intrinsic mean (mean of logs is zero), so PCA needs no further centring.
    _, s, vt = np.linalg.svd(w, full_matrices=False)
    variance = s**2 / max(rotations.shape[0], 1)
    basis = vt.T
    # Deterministic signs: the largest component of every direction is positive.
    idx = np.argmax(np.abs(basis), axis=0)
    basis = basis * np.sign(basis[idx, np.arange(basis.shape[1])])
    if k is not None:
        basis = basis[:, :k]
    return PGAModel(np.asarray(joints), mean, basis.copy(), variance)


def k_for_variance(model: PGAModel, fraction: float) -> int:
    """Smallest number of directions explaining at least ``fraction`` of the variance."""
    return int(np.searchsorted(model.explained(), fraction) + 1)


def coordinates(model: PGAModel, rotations: np.ndarray) -> np.ndarray:
    """Least-squares geodesic coordinates ``(frames, k)`` of poses ``(frames, n, 3, 3)`` for a (quantised,
    near-orthonormal) basis; :meth:`PGAModel.project` is the same for an orthonormal one."""
    t = model.tangent(rotations)
    v = model.basis
    gram = v.T @ v + 1e-12 * np.eye(v.shape[1])
    return np.linalg.solve(gram, v.T @ t.T).T
