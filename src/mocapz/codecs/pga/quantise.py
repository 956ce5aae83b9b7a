"""Quantisation of the PGA pose model: its integer form, split into the matrices the entropy coder sees,
and the model the decoder rebuilds from them (the encoder measures its coordinates against that one)."""

from __future__ import annotations

import numpy as np

from mocapz.codecs.pga import so3
from mocapz.codecs.pga.model import PGAModel
from mocapz.errors import FormatError

SIGMA_CODES = (-480, 160)  # range of the stored log2 standard deviations (sixteenths): 2**-30 .. 2**10 radians

def quantise_model(model: PGAModel, k: int, basis_bits: int, mean_step: float) -> tuple[np.ndarray, PGAModel]:
    """Integer form of the model and the model the decoder will rebuild from it.

    The directions are stored as *loadings* ``v_j * sigma_j`` (``sigma_j`` = standard deviation along
    ``v_j``) on a uniform grid of step ``2**-basis_bits`` radians, so every direction contributes a pose
    error of the same size; the decoder's basis is the dequantised loadings and coordinates are measured
    against it (whitened). Only the rows of joints that move are stored. ``mean_step`` is the grid step
    (radians) of the mean pose's rotation vectors.

    Returns a ``(n + 3n + k + 3mk, 1)`` integer column (moving-joint flags, mean, sigmas, loadings; ``n``
    modelled joints of which ``m`` move) and the model.
    """
    n = len(model.joints)
    sigma = np.sqrt(np.maximum(model.variance[:k], 0.0))
    if sigma.size < k:
        sigma = np.concatenate([sigma, np.zeros(k - sigma.size)])
    q_sigma = np.clip(np.round(np.log2(np.maximum(sigma, 1e-9)) * 16), *SIGMA_CODES).astype(np.int64)
    sigma = 2.0 ** (q_sigma / 16.0)
    loadings = model.basis[:, :k] * sigma[None]
    moving = np.abs(model.basis[:, : max(k, 1)]).reshape(n, 3, -1).max(axis=(1, 2)) > 0
    moving &= np.abs(loadings).reshape(n, 3, -1).max(axis=(1, 2)) * (1 << basis_bits) >= 0.5
    w_mu = so3.log(model.mean).reshape(-1)
    q_mu = np.round(w_mu / mean_step).astype(np.int64)
    rows = np.repeat(moving, 3)
    q_v = np.round(loadings[rows] * (1 << basis_bits)).astype(np.int64)
    ints = np.concatenate([moving.astype(np.int64), q_mu, q_sigma, q_v.T.ravel()])
    return ints[:, None], dequantise_model(ints[:, None], model.joints, k, basis_bits, mean_step, model.variance)


def model_matrices(ints: np.ndarray, n: int, k: int) -> list[np.ndarray]:
    """Split the model's integers into a header column (flags, mean, sigmas) and the loadings as a
    ``(3m, k)`` matrix, so the entropy coder adapts its scale to each direction."""
    flat = ints.ravel()
    head = flat[: 4 * n + k]
    return [head[:, None], flat[4 * n + k :].reshape(k, -1).T]


def model_from_matrices(head: np.ndarray, loadings: np.ndarray) -> np.ndarray:
    """Inverse of :func:`model_matrices`: the ``(n + 3n + k + 3mk, 1)`` integer column."""
    return np.concatenate([head.ravel(), loadings.T.ravel()])[:, None]


def dequantise_model(ints: np.ndarray, joints: np.ndarray, k: int, basis_bits: int, mean_step: float,
                     variance: np.ndarray | None = None) -> PGAModel:
    """Rebuild the (loadings) model from :func:`quantise_model`'s integers for the modelled ``joints``
    ``(n,)``; ``variance`` (rad^2) is carried over as is when given (the decoder has none)."""
    n = len(joints)
    flat = ints.ravel()
    if flat.size < 4 * n:
        raise FormatError(None, "corrupted PGA model (too short for the skeleton)")
    moving = flat[:n].astype(bool)
    m = int(moving.sum())
    if flat.size != 4 * n + k + 3 * m * k:
        raise FormatError(None, "corrupted PGA model (size does not match the skeleton)")
    q_sigma = flat[4 * n : 4 * n + k]
    if np.any(q_sigma < SIGMA_CODES[0]) or np.any(q_sigma > SIGMA_CODES[1]):
        raise FormatError(None, "corrupted PGA model (standard deviations out of range)")
    mean = so3.exp((flat[n : 4 * n] * mean_step).reshape(n, 3))
    sigma = 2.0 ** (q_sigma / 16.0)
    basis = np.zeros((3 * n, k))
    loadings = flat[4 * n + k :].reshape(k, 3 * m).T / float(1 << basis_bits)
    basis[np.repeat(moving, 3)] = loadings / sigma[None]
    return PGAModel(joints, mean, basis, np.zeros(0) if variance is None else variance)
