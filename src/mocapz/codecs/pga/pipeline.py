"""Pieces shared by the PGA encoder and decoder: clip analysis, model quantisation, channel rebuilding."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from mocapz.codecs.pga import so3
from mocapz.codecs.pga.effectors import rest_positions
from mocapz.codecs.pga.model import PGAModel
from mocapz.errors import FormatError, OptionError
from mocapz.format.entropy import decode_int_matrix, encode_int_matrix
from mocapz.model.kinematics import local_rotations, local_translations
from mocapz.model.skeleton import Skeleton

SIGMA_CODES = (-480, 160)  # range of the stored log2 standard deviations (sixteenths): 2**-30 .. 2**10 radians


def inner_joints(skeleton: Skeleton) -> np.ndarray:
    """Joints modelled by the PGA: every joint with rotation channels except the root."""
    return np.array([j for j in range(skeleton.n_joints) if skeleton.parents[j] >= 0 and skeleton.rotation_order[j]],
                    dtype=np.int64)


def check_skeleton(skeleton: Skeleton) -> None:
    if int((skeleton.parents < 0).sum()) != 1 or skeleton.parents[0] != -1:
        raise OptionError("the PGA codec needs a skeleton with a single root (joint 0)")
    if len(inner_joints(skeleton)) == 0:
        raise OptionError("the PGA codec needs at least one inner joint with rotation channels")


def skeleton_scale(skeleton: Skeleton) -> float:
    """Characteristic length (file units): the rest pose's largest extent."""
    rest = rest_positions(skeleton)
    ext = float((rest.max(axis=0) - rest.min(axis=0)).max())
    return ext if ext > 0 else 1.0


def position_columns(skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray]:
    """Column indices of the root's position channels and of every other joint's position channels."""
    root, other = [], []
    for j, (sl, chs) in enumerate(zip(skeleton.channel_slices(), skeleton.channels, strict=True)):
        for i, c in enumerate(chs):
            if c.endswith("position"):
                (root if j == 0 else other).append(sl.start + i)
    return np.array(root, dtype=np.int64), np.array(other, dtype=np.int64)


@dataclass
class Clip:
    """A clip broken into what the codec codes. Shapes use F = frames kept (outliers removed)."""

    local_rot: np.ndarray  # (F, J, 3, 3)
    local_trans: np.ndarray  # (F, J, 3)
    root_pos: np.ndarray  # (F, 3)
    root_rot: np.ndarray  # (F, 3, 3)
    other_pos: np.ndarray  # (F, p) non-root position channel values


def analyse(skeleton: Skeleton, channels: np.ndarray) -> Clip:
    rot = local_rotations(skeleton, channels)
    trans = local_translations(skeleton, channels)
    _, other = position_columns(skeleton)
    return Clip(rot, trans, trans[:, 0].copy(), rot[:, 0].copy(), channels[:, other].copy())


def targets_in_root_frame(points: np.ndarray, root_pos: np.ndarray, root_rot: np.ndarray) -> np.ndarray:
    """Global points ``(F, e, 3)`` expressed in the root joint's frame."""
    return np.einsum("fji,fej->fei", root_rot, points - root_pos[:, None])


# ----------------------------------------------------------------- model quantisation
def quantise_model(model: PGAModel, k: int, basis_bits: int, mean_step: float) -> tuple[np.ndarray, PGAModel]:
    """Integer form of the model and the model the decoder will rebuild from it.

    The directions are stored as *loadings* ``v_j * sigma_j`` (``sigma_j`` = standard deviation along
    ``v_j``) on a uniform grid of step ``2**-basis_bits`` radians, so every direction contributes a pose
    error of the same size; the decoder's basis is the dequantised loadings and coordinates are measured
    against it (whitened). Only the rows of joints that move are stored.

    Returns a ``(n + 3n + k + 3mk, 1)`` integer column (moving-joint flags, mean, sigmas, loadings) and
    the model.
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
    """Inverse of :func:`model_matrices`."""
    return np.concatenate([head.ravel(), loadings.T.ravel()])[:, None]


def dequantise_model(ints: np.ndarray, joints: np.ndarray, k: int, basis_bits: int, mean_step: float,
                     variance: np.ndarray | None = None) -> PGAModel:
    """Rebuild the (loadings) model from :func:`quantise_model`'s integers."""
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


def coordinates(model: PGAModel, rotations: np.ndarray) -> np.ndarray:
    """Least-squares geodesic coordinates ``(F, k)`` of poses for a (quantised, near-orthonormal) basis."""
    t = model.tangent(rotations)
    v = model.basis
    gram = v.T @ v + 1e-12 * np.eye(v.shape[1])
    return np.linalg.solve(gram, v.T @ t.T).T


# ----------------------------------------------------------------- channels
def channels_from_rotations(skeleton: Skeleton, local_rot: np.ndarray, out: np.ndarray,
                            joints: np.ndarray | None = None) -> None:
    """Write Euler channels of local rotations ``(F, J, 3, 3)`` into ``out`` ``(F, C)`` in place."""
    deg = skeleton.angle_unit == "deg"
    axis = skeleton.axis
    assert axis is not None
    slices = skeleton.channel_slices()
    todo = range(skeleton.n_joints) if joints is None else joints
    for j in todo:
        order = skeleton.rotation_order[j]
        if not order:
            continue
        r = local_rot[:, j]
        if not np.array_equal(axis[j], np.eye(3)):
            r = axis[j].T @ r @ axis[j]
        seq = order + "".join(a for a in "XYZ" if a not in order)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ang = Rotation.from_matrix(r).as_euler(seq.upper(), degrees=deg)[:, : len(order)]
        chs = skeleton.channels[j]
        for i, a in enumerate(order):
            out[:, slices[j].start + chs.index(f"{a}rotation")] = ang[:, i]


def unwrap_like(values: np.ndarray, reference: np.ndarray, period: float) -> np.ndarray:
    """Shift angles by whole periods to lie nearest a reference (keeps decoded Euler angles on the
    source's branch, e.g. 190 degrees rather than -170)."""
    return values + period * np.round((reference - values) / period)


# ----------------------------------------------------------------- int matrices
def pack_matrices(mats: list[np.ndarray]) -> bytes:
    """Entropy-code int matrices, one length-prefixed stream each, concatenated."""
    from mocapz.format.entropy import write_uvarint

    out = bytearray()
    for m in mats:
        b = encode_int_matrix(m)
        out += write_uvarint(len(b)) + b
    return bytes(out)


def unpack_matrices(data: bytes, count: int) -> list[np.ndarray]:
    from mocapz.format.entropy import read_uvarint

    out, pos = [], 0
    for _ in range(count):
        n, pos = read_uvarint(data, pos)
        if pos + n > len(data):
            raise FormatError(None, "truncated PGA stream")
        out.append(decode_int_matrix(data[pos : pos + n]))
        pos += n
    return out
