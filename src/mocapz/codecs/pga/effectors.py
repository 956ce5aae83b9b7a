"""Automatic choice of end effectors: one extremity per limb, found from the tree."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mocapz.codecs.pga.joints import rest_positions
from mocapz.errors import OptionError
from mocapz.model.skeleton import Skeleton


def path_to_root(skeleton: Skeleton, point: int) -> list[int]:
    """Joint indices from ``point`` (a joint, or an end site's carrier joint) up to the root, inclusive."""
    pp = skeleton.point_parents
    out = []
    j = int(pp[point]) if point >= skeleton.n_joints else point
    while j >= 0:
        out.append(j)
        j = int(skeleton.parents[j])
    return out


def find_effectors(skeleton: Skeleton, names: list[str] | None = None) -> np.ndarray:
    """FK point indices of the end effectors.

    With ``names`` (joint or end-site names) those points are used. Otherwise the extremities: leaf
    points (end sites, or joints without children and end sites), grouped into limbs (two leaves are in
    the same limb when the path between them is shorter than 40 % of the longest root-to-leaf path, as the
    fingers of one hand), keeping the leaf farthest from the root in each limb. For a CMU skeleton: both
    toe tips, the head top and one finger tip of each hand.
    """
    points = skeleton.point_names
    if names:
        missing = [n for n in names if n not in points]
        if missing:
            raise OptionError(f"unknown effector joint(s): {', '.join(missing)} (known: {', '.join(points)})")
        return np.array([points.index(n) for n in names], dtype=np.int64)
    # the automatic choice depends on the tree, the names and the rest offsets only: kept per skeleton (every
    # decode of a file asks for it again)
    key = (tuple(skeleton.names), skeleton.parents.tobytes(), np.asarray(skeleton.offsets, np.float64).tobytes(),
           tuple((int(j), np.asarray(off, np.float64).tobytes(), n) for j, off, n in skeleton.end_sites))
    found = _AUTOMATIC.get(key)
    if found is None:
        if len(_AUTOMATIC) >= 64:
            _AUTOMATIC.clear()
        found = _AUTOMATIC[key] = _automatic(skeleton)
    return found.copy()


_AUTOMATIC: dict[tuple, np.ndarray] = {}  # skeleton key -> its automatic effectors


def _automatic(skeleton: Skeleton) -> np.ndarray:
    """:func:`find_effectors` without names (the extremities)."""
    rest = rest_positions(skeleton)
    pp = skeleton.point_parents
    has_child = np.zeros(skeleton.n_points, dtype=bool)
    has_child[pp[pp >= 0]] = True
    leaves = [p for p in range(skeleton.n_points) if not has_child[p] and p != 0]
    if not leaves:
        return np.zeros(0, dtype=np.int64)

    def depth(p: int) -> float:
        chain_ = [p] + path_to_root(skeleton, p) if p >= skeleton.n_joints else path_to_root(skeleton, p)
        return float(sum(np.linalg.norm(rest[a] - rest[int(pp[a])]) for a in chain_ if pp[a] >= 0))

    d = {p: depth(p) for p in leaves}
    longest = max(d.values()) or 1.0
    anc = {p: set(path_to_root(skeleton, p)) for p in leaves}

    def between(a: int, b: int) -> float:
        common = anc[a] & anc[b]
        lca = max(common, key=lambda j: len(path_to_root(skeleton, j))) if common else 0
        return d[a] + d[b] - 2 * depth_joint(lca)

    def depth_joint(j: int) -> float:
        return float(sum(np.linalg.norm(rest[a] - rest[int(pp[a])]) for a in path_to_root(skeleton, j) if pp[a] >= 0))

    chosen: list[int] = []
    for p in sorted(leaves, key=lambda q: (-d[q], q)):
        if d[p] < 0.15 * longest:
            continue
        if all(between(p, c) >= 0.4 * longest for c in chosen):
            chosen.append(p)
    return np.array(sorted(chosen), dtype=np.int64)


def effector_points(skeleton: Skeleton, points: Sequence[int] | None) -> np.ndarray:
    """The given FK point indices ``(e,)``, or the automatic ones (:func:`find_effectors`) when none are given."""
    return np.asarray(points, dtype=np.int64) if points else find_effectors(skeleton)
