"""Outlier frames: isolated spikes in pose space (e.g. the T-pose cgspeed files add as frame 1), found by
the encoder and coded apart, exactly, outside the pose model."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mocapz.codecs.pga.joints import inner_joints
from mocapz.errors import FormatError
from mocapz.format.entropy import pack_uint64, unpack_uint64, unzigzag, zigzag
from mocapz.model.kinematics import local_rotations
from mocapz.model.motion import Motion


def detect_outliers(motion: Motion, factor: float = 15.0, local: np.ndarray | None = None) -> list[int]:
    """Frames that are isolated spikes in pose space (e.g. the T-pose cgspeed files add as frame 1).

    With ``step(a, b)`` the geodesic distance (radians) between the inner-joint poses of frames ``a`` and
    ``b`` and ``s`` its median over consecutive frames: an inner frame ``t`` is an outlier when
    ``step(t-1, t)`` and ``step(t, t+1)`` both exceed ``factor * s`` while ``step(t-1, t+1)`` does not (its
    neighbours agree with each other: a spike, not a fast move); the first (last) frame when its step to
    the next (previous) exceeds ``factor * s`` and that frame's own next step is ordinary (under ``3 s``).
    ``local``: the clip's local joint rotations ``(frames, joints, 3, 3)``, when the caller has them.
    """
    if motion.n_frames < 8:
        return []
    sk = motion.skeleton
    rot = local_rotations(sk, motion.channels) if local is None else local
    inner = inner_joints(sk)
    n = len(rot)
    step = _steps(rot, 1, inner)
    skip = _steps(rot, 2, inner)
    s = max(float(np.median(step)), 1e-9)
    out = []
    if step[0] > factor * s and step[1] < 3 * s:
        out.append(0)
    big = step > factor * s
    inner_t = np.flatnonzero(big[:-1] & big[1:] & (skip < factor * s)) + 1
    out += [int(t) for t in inner_t]
    if step[-1] > factor * s and step[-2] < 3 * s:
        out.append(n - 1)
    return sorted(set(out))


def _steps(rot: np.ndarray, lag: int, joints: np.ndarray) -> np.ndarray:
    """Geodesic distance (radians) ``(frames - lag,)`` between the poses of the ``joints`` in ``rot`` ``(frames,
    all joints, 3, 3)`` of frames ``lag`` apart: the root of the summed squared angles of the joints' relative
    rotations ``a.T @ b``, each ``acos((trace - 1) / 2)`` (the trace of ``a.T @ b`` is the sum of ``a * b``: no
    product made, and no copy of the joints' rotations)."""
    trace = np.einsum("fjab,fjab->fj", rot[:-lag], rot[lag:])[:, joints]
    cos = np.clip((trace - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(cos)
    return np.sqrt((angle * angle).sum(axis=1))


def kept_frames(frames: int, outliers: Sequence[int] | np.ndarray) -> np.ndarray:
    """Indices ``(F,)`` of the frames the pose model codes: all ``frames`` but the outliers."""
    return np.setdiff1d(np.arange(frames), np.asarray(outliers, dtype=np.int64))


def encode_outliers(motion: Motion, frames: list[int]) -> bytes:
    """Outlier frames' channels exactly at the source's precision: integers at the largest decimal count of
    any column (4 when unknown), which represents every column exactly."""
    dec = int(min(motion.decimals.max(), 9)) if motion.decimals is not None and motion.decimals.size else 4
    vals = np.round(motion.channels[frames] * 10.0**dec).astype(np.int64)
    return pack_uint64(zigzag(np.concatenate([[dec], vals.ravel()])))


def decode_outliers(data: bytes, count: int, n_channels: int) -> np.ndarray:
    """Inverse of :func:`encode_outliers`: channel values ``(count, n_channels)`` in file units."""
    raw = unzigzag(unpack_uint64(data, count * n_channels + 1))
    if not 0 <= raw[0] <= 9:
        raise FormatError(None, "corrupted PGA stream (outlier frames)")
    return raw[1:].reshape(count, n_channels) / 10.0 ** int(raw[0])
