"""Automatic hierarchy for marker data (paper §III.A, Fig. 3).

From standard CMU / Vicon Plug-in-Gait marker names (C7 at the root; head, torso and shoulders under it;
arms, hips, thighs and legs below), and for unknown names from the markers' rigidity (the spread of their
mutual distances) and proximity.
"""

from __future__ import annotations

import re

import numpy as np

from mocapz.codecs.patterns.hierarchy import Hierarchy, Node, topological
from mocapz.errors import MocapzError
from mocapz.metrics.figures import pair_distances

# ------------------------------------------------------------------ standard marker names
# node -> (parent node, preferred reference markers, members). CMU / Vicon Plug-in-Gait names.
_STANDARD: dict[str, tuple[str | None, tuple[str, ...], tuple[str, ...]]] = {
    "root": (None, ("C7",), ("C7",)),
    "head": ("root", ("LFHD",), ("LFHD", "RFHD", "LBHD", "RBHD")),
    "torso": ("root", ("T10", "STRN"), ("T10", "CLAV", "STRN", "RBAC", "RBAK", "LBAC", "LBAK", "T8", "SACR")),
    "lshoulder": ("root", ("LSHO",), ("LSHO",)),
    "rshoulder": ("root", ("RSHO",), ("RSHO",)),
    "larm": ("lshoulder", ("LELB",), ("LUPA", "LELB")),
    "rarm": ("rshoulder", ("RELB",), ("RUPA", "RELB")),
    "lforearm": ("larm", ("LWRA",), ("LFRM", "LWRA", "LWRB", "LFIN")),
    "rforearm": ("rarm", ("RWRA",), ("RFRM", "RWRA", "RWRB", "RFIN")),
    "lhip": ("torso", ("LFWT", "LASI"), ("LFWT", "LBWT", "LASI", "LPSI")),
    "rhip": ("torso", ("RFWT", "RASI"), ("RFWT", "RBWT", "RASI", "RPSI")),
    "lthigh": ("lhip", ("LKNE",), ("LTHI", "LKNE")),
    "rthigh": ("rhip", ("RKNE",), ("RTHI", "RKNE")),
    "lleg": ("lthigh", ("LANK",), ("LSHN", "LTIB", "LANK", "LHEE", "LTOE", "LMT5")),
    "rleg": ("rthigh", ("RANK",), ("RSHN", "RTIB", "RANK", "RHEE", "RTOE", "RMT5")),
}
_ROOT_FALLBACK = ("C7", "CLAV", "T10", "STRN")
HEAD_DIAGONALS = (("LFHD", "RBHD"), ("RFHD", "LBHD"))
INSEPARABLE = 2.0**-40  # a group whose rigidity spread is below this share of the cut is split without it


def canonical_label(label: str) -> str:
    """Upper-case marker name without a ``Subject:`` prefix (``"Daphnee:LFHD"`` -> ``"LFHD"``)."""
    return re.sub(r"^.*:", "", label).strip().upper()


def standard_node_of(labels: list[str]) -> dict[int, str]:
    """Marker index -> standard node name, for the labels found in the standard table."""
    table = {name: node for node, (_, _, members) in _STANDARD.items() for name in members}
    out, seen = {}, set()
    for i, lab in enumerate(labels):
        name = canonical_label(lab)
        if name in table and name not in seen:
            out[i] = table[name]
            seen.add(name)
    return out


def _stats(positions: np.ndarray, max_frames: int = 400) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairwise rigidity (std of distance), mean distance and common-frame counts, ``(M, M)`` each, over at most
    about ``max_frames`` frames ``(frames, M, 3)``; a few rows at a time (:func:`.pair_distances`), so a
    marker set of hundreds of points (a model's outputs stored as points) needs no frames x M x M x 3 array."""
    step = max(1, positions.shape[0] // max_frames)
    sub = positions[::step]
    m = sub.shape[1]
    rig, mean, cnt = np.empty((m, m)), np.empty((m, m)), np.empty((m, m), dtype=np.int64)
    for rows, d in pair_distances(sub):
        ok = np.isfinite(d)
        c = cnt[rows] = ok.sum(axis=0)
        mu = mean[rows] = np.where(ok, d, 0.0).sum(axis=0) / np.maximum(c, 1)
        rig[rows] = np.sqrt((np.where(ok, d - mu, 0.0) ** 2).sum(axis=0) / np.maximum(c, 1))
    return rig, mean, cnt


def attach_by_rigidity(unassigned: list[int], owner: dict[int, int], positions: np.ndarray) -> dict[int, int]:
    """Give each unassigned marker the node of its most rigid (then nearest) assigned marker."""
    if not unassigned:
        return {}
    rig, mean, cnt = _stats(positions)
    assigned = np.array(sorted(owner), dtype=np.int64)
    out = {}
    for u in unassigned:
        c = cnt[u, assigned]
        good = assigned[c >= 10]
        if good.size:
            score = rig[u, good] + 0.05 * mean[u, good]
            out[u] = owner[int(good[np.argmin(score)])]
        elif (c > 0).any():
            some = assigned[c > 0]
            out[u] = owner[int(some[np.argmin(mean[u, some])])]
        else:
            out[u] = -1
    return out


def build_marker_hierarchy(labels: list[str], positions: np.ndarray) -> Hierarchy:
    """Hierarchy for a marker set: standard names first, rigidity/proximity for the rest.

    Args:
        labels: marker names.
        positions: ``(frames, markers, 3)`` with NaN gaps.
    """
    m = len(labels)
    if m == 0:
        raise MocapzError("no markers: nothing to compress")
    known = standard_node_of(labels)
    if len(set(known.values()) - {"root"}) < 3 or not any(canonical_label(labels[i]) in _ROOT_FALLBACK
                                                          for i in known):
        return auto_marker_hierarchy(positions)
    canon = {canonical_label(labels[i]): i for i in known}
    root_marker = next(canon[n] for n in _ROOT_FALLBACK if n in canon)
    groups: dict[str, list[int]] = {}
    for i, node in known.items():
        if i != root_marker:
            groups.setdefault("torso" if node == "root" else node, []).append(i)
    names = ["root"] + [n for n in _STANDARD if n != "root" and n in groups]
    index = {n: k for k, n in enumerate(names)}
    owner = {root_marker: 0} | {i: index[n] for n, mem in groups.items() for i in mem}
    rest = [i for i in range(m) if i not in owner]
    attached = attach_by_rigidity(rest, owner, positions)
    members: list[list[int]] = [[root_marker]] + [sorted(groups[n]) for n in names[1:]]
    orphans = []
    for u, k in attached.items():
        if k <= 0:
            orphans.append(u)
        else:
            members[k].append(u)
    if orphans:
        names.append("extra")
        members.append(orphans)
    nodes = []
    for k, name in enumerate(names):
        parent_name = _STANDARD.get(name, ("root",))[0]
        while parent_name is not None and parent_name not in index:
            parent_name = _STANDARD[parent_name][0]
        prefs = _STANDARD[name][1] if name in _STANDARD else ()
        ref = next((canon[p] for p in prefs if p in canon and canon[p] in members[k]), members[k][0])
        nodes.append(Node(name, members[k], -1 if k == 0 else index.get(parent_name or "root", 0), ref))
    return topological(nodes)


def auto_marker_hierarchy(positions: np.ndarray, max_group: int = 6) -> Hierarchy:
    """Hierarchy from the markers alone: rigid groups (distance spread) joined by proximity.

    The root marker is the most central of the best-observed markers; markers that keep their mutual
    distances (average-linkage clustering of the distance spread, cut at 5 % of the body scale, groups of
    at most ``max_group``) become nodes, connected by a minimum spanning tree over the groups' nearest
    distances, rooted at the root marker. Markers never observed form one node under the root.
    """
    from scipy.cluster.hierarchy import fcluster, linkage
    from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

    m = positions.shape[1]
    if m == 0:
        raise MocapzError("no markers: nothing to compress")
    rig, mean, cnt = _stats(positions)
    observed = np.isfinite(positions).all(axis=2).mean(axis=0)
    seen = np.flatnonzero(observed > 0)
    if seen.size == 0:
        return Hierarchy([Node("root", [0], -1, 0)] + ([Node("unobserved", list(range(1, m)), 0, 1)] if m > 1 else []))
    with np.errstate(invalid="ignore"):
        central = np.where(cnt > 0, mean, np.nan)[np.ix_(seen, seen)]
        central = np.nanmean(central, axis=1)
    good = observed[seen] >= 0.9 * observed[seen].max()
    root = int(seen[np.flatnonzero(good)[np.nanargmin(central[good])]] if np.isfinite(central[good]).any()
               else seen[np.argmax(observed[seen])])
    others = [i for i in seen.tolist() if i != root]
    nodes = [Node("root", [root], -1, root)]
    if others:
        with np.errstate(invalid="ignore"):
            extent = np.nanmedian(np.nanmax(positions, axis=1) - np.nanmin(positions, axis=1), axis=0)
        scale = 0.11 * float(np.nanmax(extent)) if np.isfinite(extent).any() else 1.0
        spread = np.where(cnt >= 10, rig, 10.0 * scale + mean)
        labels = _rigid_groups(spread, others, max_group, 0.05 * scale, linkage, fcluster)
        groups = [[others[i] for i in np.flatnonzero(labels == g)] for g in np.unique(labels)]
        members = [[root]] + groups
        n = len(groups)
        dist = np.zeros((n + 1, n + 1))
        for a in range(n + 1):
            for b in range(a + 1, n + 1):
                near = np.where(cnt[np.ix_(members[a], members[b])] > 0, mean[np.ix_(members[a], members[b])], np.inf)
                dist[a, b] = dist[b, a] = min(float(near.min()), 1e12) + 1e-9
        order, pred = breadth_first_order(minimum_spanning_tree(dist), 0, directed=False)
        pos_of = {0: 0}
        for g in order[1:]:
            pos_of[int(g)] = len(nodes)
            nodes.append(Node(f"part{len(nodes)}", members[g], pos_of[int(pred[g])], members[g][0]))
        for k, node in enumerate(nodes[1:], start=1):
            kids = [c for c in range(len(nodes)) if nodes[c].parent == k]
            if kids:
                child = [i for c in kids for i in nodes[c].members]
                node.reference = node.members[int(np.argmin(mean[np.ix_(node.members, child)].mean(axis=1)))]
    never = [i for i in range(m) if observed[i] == 0]
    if never:
        nodes.append(Node("unobserved", never, 0, never[0]))
    return Hierarchy(nodes)


def _rigid_groups(rig: np.ndarray, idx: list[int], max_group: int, cut: float, linkage, fcluster) -> np.ndarray:
    """Cluster labels over ``idx``: average linkage on rigidity cut at ``cut``, large groups split again."""
    if len(idx) == 1:
        return np.zeros(1, dtype=np.int64)
    sub = rig[np.ix_(idx, idx)]
    z = linkage(sub[np.triu_indices(len(idx), 1)], method="average")
    if len(idx) > max_group and not z[-1, 2] > cut * INSEPARABLE:
        # points rigid with one another to the last bit (a model's virtual points on a segment's markers): no cut
        # separates them, so they are split in order into groups of the largest size
        return np.arange(len(idx), dtype=np.int64) // max_group
    lab = fcluster(z, cut, criterion="distance").astype(np.int64)
    out = np.zeros(len(idx), dtype=np.int64)
    nxt = 0
    for g in np.unique(lab):
        rows = np.flatnonzero(lab == g)
        if len(rows) > max_group:
            part = _rigid_groups(rig, [idx[r] for r in rows], max_group, cut * 0.5, linkage, fcluster)
            out[rows] = part + nxt
            nxt += int(part.max()) + 1
        else:
            out[rows] = nxt
            nxt += 1
    return out
