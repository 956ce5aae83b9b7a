"""Batched forward kinematics: all frames at once, one vectorised step per joint."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mocapz.model.skeleton import Skeleton


def local_rotations(skeleton: Skeleton, channels: np.ndarray) -> np.ndarray:
    """Local rotation matrices ``(frames, joints, 3, 3)`` from channel values ``(frames, channels)``."""
    frames = channels.shape[0]
    out = np.broadcast_to(np.eye(3), (frames, skeleton.n_joints, 3, 3)).copy()
    scale = np.pi / 180.0 if skeleton.angle_unit == "deg" else 1.0
    axis = skeleton.axis
    assert axis is not None
    for j, (sl, chs, order) in enumerate(
        zip(skeleton.channel_slices(), skeleton.channels, skeleton.rotation_order, strict=True)
    ):
        if not order:
            continue
        cols = [sl.start + chs.index(f"{a}rotation") for a in order]
        angles = channels[:, cols] * scale
        r = Rotation.from_euler(order.upper(), angles).as_matrix()
        if not np.array_equal(axis[j], np.eye(3)):
            r = axis[j] @ r @ axis[j].T
        out[:, j] = r
    return out


def local_translations(skeleton: Skeleton, channels: np.ndarray) -> np.ndarray:
    """Local translations ``(frames, joints, 3)``: offsets, replaced by position channels where present."""
    frames = channels.shape[0]
    out = np.broadcast_to(skeleton.offsets, (frames, skeleton.n_joints, 3)).copy()
    for j, (sl, chs) in enumerate(zip(skeleton.channel_slices(), skeleton.channels, strict=True)):
        for k, c in enumerate(chs):
            if c.endswith("position"):
                out[:, j, "XYZ".index(c[0])] = channels[:, sl.start + k]
    return out


def forward_kinematics(skeleton: Skeleton, channels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Global positions and rotations of a skeleton for every frame.

    Args:
        skeleton: the hierarchy.
        channels: ``(frames, channels)`` values in file units.

    Returns:
        positions ``(frames, joints + end_sites, 3)`` in file units (joints then end sites) and
        global rotations ``(frames, joints, 3, 3)``.
    """
    channels = np.asarray(channels, dtype=np.float64)
    rot = local_rotations(skeleton, channels)
    trans = local_translations(skeleton, channels)
    return chain(skeleton, rot, trans)


def chain(skeleton: Skeleton, rot: np.ndarray, trans: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Compose local rotations ``(F, J, 3, 3)`` and translations ``(F, J, 3)`` down the tree."""
    frames, n = rot.shape[0], skeleton.n_joints
    g_rot = np.empty_like(rot)
    pos = np.empty((frames, skeleton.n_points, 3))
    for j in range(n):
        p = skeleton.parents[j]
        if p < 0:
            g_rot[:, j] = rot[:, j]
            pos[:, j] = trans[:, j]
        else:
            g_rot[:, j] = g_rot[:, p] @ rot[:, j]
            pos[:, j] = pos[:, p] + np.einsum("fab,fb->fa", g_rot[:, p], trans[:, j])
    for e, (j, off, _) in enumerate(skeleton.end_sites):
        pos[:, n + e] = pos[:, j] + g_rot[:, j] @ np.asarray(off)
    return pos, g_rot
