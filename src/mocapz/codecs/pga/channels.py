"""Poses written back as channel values: Euler angles of the local rotations (in the skeleton's angle
unit, unwrapped over time) and the position channels."""

from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from mocapz.codecs.pga.joints import position_columns
from mocapz.model.skeleton import Skeleton


def channels_from_rotations(skeleton: Skeleton, local_rot: np.ndarray, out: np.ndarray,
                            joints: np.ndarray | None = None) -> None:
    """Write Euler channels (the skeleton's angle unit) of local rotations ``(F, J, 3, 3)`` into ``out``
    ``(F, C)`` in place, for the given joints (all when None)."""
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


def channels_from_pose(skeleton: Skeleton, local_rot: np.ndarray, root_pos: np.ndarray,
                       other: np.ndarray) -> np.ndarray:
    """Channel values ``(F, C)`` of local rotations ``(F, J, 3, 3)``, the root position ``(F, 3)`` and the
    non-root position channels ``(F, p)`` (file units). Angles are unwrapped along time (a full turn is
    360 degrees or 2 pi radians, by the skeleton's angle unit). Always finite (NaN and inf replaced)."""
    n = local_rot.shape[0]
    root_cols, other_cols = position_columns(skeleton)
    out = np.zeros((n, skeleton.n_channels))
    channels_from_rotations(skeleton, local_rot, out)
    rot_cols = skeleton.rotation_columns()
    period = 360.0 if skeleton.angle_unit == "deg" else 2 * np.pi
    out[:, rot_cols] = np.unwrap(out[:, rot_cols], period=period, axis=0)
    labels = skeleton.channel_labels()
    for c in root_cols:
        out[:, c] = root_pos[:, "XYZ".index(labels[c].split(".")[-1][0])]
    out[:, other_cols] = other
    return np.nan_to_num(out)
