"""The skeleton model shared by every skeletal format (BVH, ASF/AMC).

A :class:`Skeleton` is a tree of joints. Joint ``j`` sits at ``offset[j]`` in its parent's frame (in the
file's length unit) unless it has position channels, which then replace the offset (the BVH convention of
Blender and three.js). Its local rotation is ``axis[j] @ R(channels) @ axis[j].T``, where ``R`` composes the
elementary rotations in ``rotation_order[j]`` (``"ZXY"`` means ``R = Rz @ Rx @ Ry``) and ``axis`` is the
identity for BVH and the ASF ``axis`` frame for Acclaim skeletons. End sites are extra points carried
by a joint (BVH ``End Site``, ASF leaf-bone tips); they have no channels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: BVH channel names, the project's canonical channel vocabulary.
POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")
ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
CHANNEL_NAMES = POSITION_CHANNELS + ROTATION_CHANNELS


@dataclass
class Skeleton:
    """Joint hierarchy with rest offsets and channel layout.

    Attributes:
        names: joint names, parents before children (topological order).
        parents: parent index per joint, ``-1`` for the root(s).
        offsets: ``(joints, 3)`` rest translation from the parent joint, in file units.
        channels: per joint, the names of its channels in file column order (subset of
            :data:`CHANNEL_NAMES`).
        rotation_order: per joint, the axes of its rotation channels in matrix-product order
            (``""`` for a joint without rotation channels).
        axis: ``(joints, 3, 3)`` rest frame of each joint's rotation (identity for BVH).
        end_sites: ``(parent joint index, offset (3,), name)`` for each end site.
        angle_unit: ``"deg"`` or ``"rad"``, the unit of the rotation channel values.
        unit_cm: centimetres per file length unit, or ``None`` if unknown.
        unit_note: how ``unit_cm`` was determined (for reports).
        extra: format-specific data needed to write the skeleton back (e.g. the ASF text).
    """

    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: list[tuple[str, ...]]
    rotation_order: list[str]
    axis: np.ndarray | None = None
    end_sites: list[tuple[int, np.ndarray, str]] = field(default_factory=list)
    angle_unit: str = "deg"
    unit_cm: float | None = None
    unit_note: str = "unknown"
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.parents = np.asarray(self.parents, dtype=np.int64)
        self.offsets = np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3)
        n = len(self.names)
        if self.axis is None:
            self.axis = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
        late = np.flatnonzero(self.parents >= np.arange(self.parents.size))
        if late.size:
            raise ValueError(f"joint {self.names[late[0]]!r}: parent must come before child")

    # ----------------------------------------------------------------- layout
    @property
    def n_joints(self) -> int:
        return len(self.names)

    @property
    def n_channels(self) -> int:
        return sum(len(c) for c in self.channels)

    @property
    def n_points(self) -> int:
        """Number of FK points: joints then end sites."""
        return self.n_joints + len(self.end_sites)

    @property
    def point_names(self) -> list[str]:
        return list(self.names) + [name for _, _, name in self.end_sites]

    @property
    def point_parents(self) -> np.ndarray:
        """Parent point index of every FK point (joints, then end sites)."""
        ends = np.array([j for j, _, _ in self.end_sites], dtype=np.int64)
        return np.concatenate([self.parents, ends])

    def below(self) -> np.ndarray:
        """``(joints, points)`` bool: ``below[a, p]`` is True when FK point ``p`` (joints, then end sites) lies
        strictly below joint ``a`` in the hierarchy (a rotation of ``a`` moves ``p``)."""
        parents = self.point_parents
        out = np.zeros((self.n_joints, self.n_points), dtype=bool)
        for p in range(self.n_points):
            q = parents[p]
            while q >= 0:
                out[q, p] = True
                q = parents[q]
        return out

    def channel_slices(self) -> list[slice]:
        """Column range of each joint's channels in the motion's channel matrix."""
        out, start = [], 0
        for ch in self.channels:
            out.append(slice(start, start + len(ch)))
            start += len(ch)
        return out

    def channel_labels(self) -> list[str]:
        """``joint.channel`` label of every column."""
        return [f"{n}.{c}" for n, chs in zip(self.names, self.channels, strict=True) for c in chs]

    def rotation_columns(self) -> np.ndarray:
        """Boolean mask over columns: True for rotation channels."""
        return np.array([c.endswith("rotation") for chs in self.channels for c in chs], dtype=bool)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint named {name!r}") from None

    def children(self, j: int) -> list[int]:
        return [int(c) for c in np.flatnonzero(self.parents == j)]

    def has_identity_axes(self) -> bool:
        assert self.axis is not None
        return bool(np.allclose(self.axis, np.eye(3)[None], atol=1e-12))

    def copy(self) -> Skeleton:
        return Skeleton(
            names=list(self.names),
            parents=self.parents.copy(),
            offsets=self.offsets.copy(),
            channels=list(self.channels),
            rotation_order=list(self.rotation_order),
            axis=None if self.axis is None else self.axis.copy(),
            end_sites=[(j, np.array(o, dtype=np.float64), n) for j, o, n in self.end_sites],
            angle_unit=self.angle_unit,
            unit_cm=self.unit_cm,
            unit_note=self.unit_note,
            extra=dict(self.extra),
        )

    def body_points(self) -> np.ndarray:
        """Indices of the body's FK points (joints, then end sites): the subtree of the first joint that
        branches, so that a chain of helper joints above the hips (a locomotion root on the floor, as in the
        Bandai-Namco rigs) is left out. ``(points,)`` int64, increasing."""
        top = 0
        while (kids := np.flatnonzero(self.parents == top)).size == 1:
            top = int(kids[0])
        inside = np.zeros(self.n_points, dtype=bool)
        inside[top] = True
        parents = self.point_parents
        for p in range(top + 1, self.n_points):  # parents come before children, joints before end sites
            inside[p] = parents[p] >= 0 and inside[parents[p]]
        return np.flatnonzero(inside)
