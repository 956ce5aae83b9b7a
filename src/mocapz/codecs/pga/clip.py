"""A clip broken into what the PGA codec codes: local rotations and translations, the root trajectory and
the non-root position channels; and points expressed in the root joint's frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapz.codecs.pga.joints import position_columns
from mocapz.model.kinematics import local_rotations, local_translations
from mocapz.model.skeleton import Skeleton


@dataclass
class Clip:
    """A clip broken into what the codec codes. Shapes use F = frames kept (outliers removed), J = joints;
    lengths in file units."""

    local_rot: np.ndarray  # (F, J, 3, 3)
    local_trans: np.ndarray  # (F, J, 3)
    root_pos: np.ndarray  # (F, 3)
    root_rot: np.ndarray  # (F, 3, 3)
    other_pos: np.ndarray  # (F, p) non-root position channel values


def analyse(skeleton: Skeleton, channels: np.ndarray, rot: np.ndarray | None = None) -> Clip:
    """Break channel values ``(F, C)`` (file units and the skeleton's angle unit) into a :class:`Clip`. ``rot``:
    their local joint rotations ``(F, joints, 3, 3)`` (:func:`~mocapz.model.kinematics.local_rotations`), when
    the caller has them."""
    rot = local_rotations(skeleton, channels) if rot is None else rot
    trans = local_translations(skeleton, channels)
    _, other = position_columns(skeleton)
    return Clip(rot, trans, trans[:, 0].copy(), rot[:, 0].copy(), channels[:, other].copy())


def targets_in_root_frame(points: np.ndarray, root_pos: np.ndarray, root_rot: np.ndarray) -> np.ndarray:
    """Global points ``(F, e, 3)`` expressed in the root joint's frame (root position ``(F, 3)``,
    orientation ``(F, 3, 3)``); file units."""
    return np.einsum("fji,fej->fei", root_rot, points - root_pos[:, None])
