"""What the encoder derives from a motion before coding: hierarchy, member weights, length scale (ADDH)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mocapz.codecs.patterns.hierarchy import Hierarchy
from mocapz.codecs.patterns.hierarchy_json import hierarchy_from_json
from mocapz.codecs.patterns.marker_tree import HEAD_DIAGONALS, build_marker_hierarchy, canonical_label
from mocapz.codecs.patterns.options import parse_weights
from mocapz.codecs.patterns.skeletal import HEAD_TO_HEIGHT, skeleton_addh
from mocapz.codecs.patterns.skeleton_tree import build_skeleton_hierarchy
from mocapz.errors import FormatError, OptionError
from mocapz.model.motion import AnyMotion, MarkerMotion

ADDH_FRAMES = 200  # paper §V.a: the head diagonals are averaged over the first frames


@dataclass
class Prepared:
    """Hierarchy, ``(members,)`` weights and the ADDH (file units) of one motion."""

    hier: Hierarchy
    weights: np.ndarray
    addh: float


def member_names(motion: AnyMotion) -> list[str]:
    return list(motion.labels) if isinstance(motion, MarkerMotion) else list(motion.skeleton.names)


def marker_addh(labels: list[str], positions: np.ndarray) -> float:
    """Average diagonal distance of the head markers over the first frames (paper §V.a).

    Without the four head markers: 11 % of the body's median vertical extent (the ratio on CMU subjects).
    """
    canon = {canonical_label(n): i for i, n in enumerate(labels)}
    head = positions[:ADDH_FRAMES]
    dists = []
    for a, b in HEAD_DIAGONALS:
        if a in canon and b in canon:
            d = np.linalg.norm(head[:, canon[a]] - head[:, canon[b]], axis=1)
            dists.append(d[np.isfinite(d)])
    vals = np.concatenate(dists) if dists else np.zeros(0)
    if vals.size >= 10 and vals.mean() > 0:
        return float(vals.mean())
    with np.errstate(invalid="ignore"):
        ext = np.nanmax(positions, axis=1) - np.nanmin(positions, axis=1)
        extent = np.nanmedian(ext, axis=0)
    top = float(np.nanmax(extent)) if np.isfinite(extent).any() else 0.0
    return HEAD_TO_HEIGHT * top if top > 0 else 1.0


def prepare(motion: AnyMotion, hierarchy: Any = None, weights: Any = None) -> Prepared:
    """Build (or read) the hierarchy, the weights and the ADDH of a motion; bad input -> MocapzError."""
    where = motion.metadata.get("path", motion.name)
    if isinstance(motion, MarkerMotion):
        if motion.n_markers == 0:
            raise FormatError(where, "no markers: nothing for the patterns codec to compress")
        if hierarchy is not None:
            hier = hierarchy_from_json(hierarchy, motion.labels, positions=motion.positions)
        else:
            hier = build_marker_hierarchy(motion.labels, motion.positions)
        addh = marker_addh(motion.labels, motion.positions)
    else:
        sk = motion.skeleton
        if sk.n_channels == 0:
            raise FormatError(where, "the skeleton has no channels: nothing to compress")
        if hierarchy is not None:
            hier = hierarchy_from_json(hierarchy, sk.names, parents=sk.parents)
            root = int(np.flatnonzero(sk.parents < 0)[0])
            if hier.nodes[0].reference != root:
                raise OptionError(f"{hierarchy}: hierarchy: the root node must hold the root joint {sk.names[root]!r}")
        else:
            hier = build_skeleton_hierarchy(sk)
        addh = skeleton_addh(sk)
    hier.validate(len(member_names(motion)))
    return Prepared(hier, parse_weights(weights, member_names(motion), str(where)), addh)
