"""The skeleton as the PGA codec sees it: which joints the pose model drives, which channels are positions,
the rest pose and the skeleton's size, and the checks a skeleton must pass."""

from __future__ import annotations

import numpy as np

from mocapz.errors import OptionError
from mocapz.model.kinematics import chain
from mocapz.model.skeleton import Skeleton


def inner_joints(skeleton: Skeleton) -> np.ndarray:
    """Joints modelled by the PGA ``(n,)``: every joint with rotation channels except the root."""
    return np.array([j for j in range(skeleton.n_joints) if skeleton.parents[j] >= 0 and skeleton.rotation_order[j]],
                    dtype=np.int64)


def check_skeleton(skeleton: Skeleton) -> None:
    """Raise :class:`OptionError` unless the skeleton has a single root (joint 0) and an inner joint."""
    if int((skeleton.parents < 0).sum()) != 1 or skeleton.parents[0] != -1:
        raise OptionError("the PGA codec needs a skeleton with a single root (joint 0)")
    if len(inner_joints(skeleton)) == 0:
        raise OptionError("the PGA codec needs at least one inner joint with rotation channels")


def position_columns(skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray]:
    """Column indices of the root's position channels and of every other joint's position channels."""
    root, other = [], []
    for j, (sl, chs) in enumerate(zip(skeleton.channel_slices(), skeleton.channels, strict=True)):
        for i, c in enumerate(chs):
            if c.endswith("position"):
                (root if j == 0 else other).append(sl.start + i)
    return np.array(root, dtype=np.int64), np.array(other, dtype=np.int64)


def column_joints(skeleton: Skeleton) -> dict[int, tuple[int, str]]:
    """Channel column -> (joint index, axis letter ``"X"``, ``"Y"`` or ``"Z"``)."""
    cj = {}
    for j, (sl, chs) in enumerate(zip(skeleton.channel_slices(), skeleton.channels, strict=True)):
        for i, c in enumerate(chs):
            cj[sl.start + i] = (j, c[0])
    return cj


def rest_positions(skeleton: Skeleton) -> np.ndarray:
    """Rest-pose positions ``(points, 3)`` (file units; all rotations zero, offsets only)."""
    n = skeleton.n_joints
    rot = np.broadcast_to(np.eye(3), (1, n, 3, 3)).copy()
    return chain(skeleton, rot, skeleton.offsets[None].copy())[0][0]


def skeleton_scale(skeleton: Skeleton) -> float:
    """Characteristic length (file units): the rest pose's largest extent."""
    rest = rest_positions(skeleton)
    ext = float((rest.max(axis=0) - rest.min(axis=0)).max())
    return ext if ext > 0 else 1.0
