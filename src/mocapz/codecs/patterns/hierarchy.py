"""Body-part hierarchy (paper §III.A): nodes of markers (or joints), each relative to its parent.

A :class:`Hierarchy` is a list of :class:`Node` in topological order (parents first); ``nodes[0]`` is the
root node, holding the single root marker (the one behind the top of the spine, C7) whose absolute
positions are coded per frame. Every other node's members are coded relative to the *reference* member
of its parent node (the member near the joint with the children).

Hierarchies are built automatically (:func:`build_marker_hierarchy` from standard CMU / Vicon marker names
and, for unknown names, from the markers' rigidity and proximity; :func:`build_skeleton_hierarchy` from the
joint tree), or read from a small JSON file (:mod:`.hierarchy_json`). They are stored in the stream with
:meth:`Hierarchy.to_bytes`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ...entropy import read_uvarint, write_uvarint
from ...errors import FormatError, MocapzError
from ...skeleton import Skeleton


@dataclass
class Node:
    """One body part.

    Attributes:
        name: body-part name (``"root"``, ``"head"``, ``"larm"``...).
        members: marker indices (marker data) or joint indices (skeletons), in coding order.
        parent: index of the parent node, ``-1`` for the root node.
        reference: the member (marker / joint index) the children are expressed relative to.
    """

    name: str
    members: list[int]
    parent: int
    reference: int


@dataclass
class Hierarchy:
    """Nodes in topological order; ``nodes[0]`` is the root node."""

    nodes: list[Node]

    def children(self, k: int) -> list[int]:
        return [i for i, n in enumerate(self.nodes) if n.parent == k]

    @property
    def names(self) -> list[str]:
        return [n.name for n in self.nodes]

    def signature(self) -> tuple:
        """What must agree for two clips to share pattern databases (names and member counts)."""
        return tuple((n.name, len(n.members), n.parent) for n in self.nodes)

    def validate(self, n_members: int) -> None:
        """Check structure: root first, parents before children, every member at most once."""
        seen: set[int] = set()
        if not self.nodes or self.nodes[0].parent != -1:
            raise MocapzError("hierarchy: the first node must be the root (no parent)")
        for k, node in enumerate(self.nodes):
            if k and not 0 <= node.parent < k:
                raise MocapzError(f"hierarchy: node {node.name!r} must come after its parent")
            if not node.members:
                raise MocapzError(f"hierarchy: node {node.name!r} has no members")
            for m in node.members:
                if not 0 <= m < n_members or m in seen:
                    raise MocapzError(f"hierarchy: member {m} of node {node.name!r} is out of range or repeated")
                seen.add(m)
            if node.reference not in node.members:
                raise MocapzError(f"hierarchy: reference of node {node.name!r} is not one of its members")

    # ------------------------------------------------------------ serialisation
    def to_bytes(self, with_names: bool = False) -> bytes:
        """Compact varint form: node count, then per node parent+1, reference position, members."""
        out = bytearray(write_uvarint(len(self.nodes)) + bytes([1 if with_names else 0]))
        for n in self.nodes:
            out += write_uvarint(n.parent + 1) + write_uvarint(n.members.index(n.reference))
            out += write_uvarint(len(n.members))
            for m in n.members:
                out += write_uvarint(m)
            if with_names:
                name = n.name.encode()
                out += write_uvarint(len(name)) + name
        return bytes(out)

    @classmethod
    def from_bytes(cls, data: bytes) -> Hierarchy:
        try:
            count, pos = read_uvarint(data, 0)
            named = data[pos]
            pos += 1
            nodes = []
            for k in range(count):
                parent, pos = read_uvarint(data, pos)
                ref, pos = read_uvarint(data, pos)
                size, pos = read_uvarint(data, pos)
                members = []
                for _ in range(size):
                    m, pos = read_uvarint(data, pos)
                    members.append(m)
                name = f"node{k}"
                if named:
                    ln, pos = read_uvarint(data, pos)
                    name = bytes(data[pos : pos + ln]).decode()
                    pos += ln
                nodes.append(Node(name, members, parent - 1, members[ref]))
        except (IndexError, UnicodeDecodeError) as exc:
            raise FormatError(None, f"corrupted pattern hierarchy ({exc})") from None
        return cls(nodes)


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
    """Pairwise rigidity (std of distance), mean distance and common-frame counts, ``(M, M)`` each."""
    step = max(1, positions.shape[0] // max_frames)
    sub = positions[::step]
    d = np.linalg.norm(sub[:, :, None] - sub[:, None, :], axis=-1)
    ok = np.isfinite(d)
    cnt = ok.sum(axis=0)
    d0 = np.where(ok, d, 0.0)
    mean = d0.sum(axis=0) / np.maximum(cnt, 1)
    var = (np.where(ok, d - mean, 0.0) ** 2).sum(axis=0) / np.maximum(cnt, 1)
    return np.sqrt(var), mean, cnt


def _attach(unassigned: list[int], owner: dict[int, int], positions: np.ndarray) -> dict[int, int]:
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
    attached = _attach(rest, owner, positions)
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
    return _sorted(nodes)


def _sorted(nodes: list[Node]) -> Hierarchy:
    """Re-order nodes so that parents precede children (root first), fixing parent indices."""
    order: list[int] = [0]
    for k in order:
        order.extend(i for i, n in enumerate(nodes) if n.parent == k and i != k)
    if len(order) != len(nodes):
        raise MocapzError("hierarchy: some nodes are not connected to the root (cycle?)")
    new = {old: k for k, old in enumerate(order)}
    out = [Node(nodes[o].name, nodes[o].members, -1 if k == 0 else new[nodes[o].parent], nodes[o].reference)
           for k, o in enumerate(order)]
    return Hierarchy(out)


def auto_marker_hierarchy(positions: np.ndarray, max_group: int = 6) -> Hierarchy:
    """Hierarchy from the markers alone: rigid groups (distance spread) joined by proximity.

    The root marker is the most central well-observed marker; groups of markers that keep their mutual
    distances (agglomerative clustering on the distance spread) become nodes, connected by a minimum
    spanning tree over the groups' nearest-marker distances, rooted at the root marker's group.
    """
    from scipy.cluster.hierarchy import fcluster, linkage
    from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

    m = positions.shape[1]
    if m == 0:
        raise MocapzError("no markers: nothing to compress")
    rig, mean, cnt = _stats(positions)
    big = np.nanmax(np.where(cnt > 0, rig, np.nan)) if (cnt > 0).any() else 1.0
    rig = np.where(cnt >= 10, rig, (big if np.isfinite(big) else 1.0) * 10 + mean)
    observed = np.isfinite(positions).all(axis=2).mean(axis=0)
    central = mean.sum(axis=1) / max(m - 1, 1) + np.where(observed > 0.9, 0.0, 1e12)
    root = int(np.argmin(central))
    if m == 1:
        return Hierarchy([Node("root", [0], -1, 0)])
    others = [i for i in range(m) if i != root]
    labels = _rigid_groups(rig, others, max_group, linkage, fcluster)
    groups = [[others[i] for i in np.flatnonzero(labels == g)] for g in np.unique(labels)]
    n = len(groups)
    # proximity graph: root (node 0) + groups (1..n)
    members = [[root]] + groups
    dist = np.zeros((n + 1, n + 1))
    for a in range(n + 1):
        for b in range(a + 1, n + 1):
            dist[a, b] = dist[b, a] = 1e-9 + mean[np.ix_(members[a], members[b])].min()
    tree = minimum_spanning_tree(dist)
    order, pred = breadth_first_order(tree, 0, directed=False)
    nodes = [Node("root", [root], -1, root)]
    pos_of = {0: 0}
    for g in order[1:]:
        pos_of[int(g)] = len(nodes)
        nodes.append(Node(f"part{len(nodes)}", members[g], pos_of[int(pred[g])], members[g][0]))
    for k, node in enumerate(nodes[1:], start=1):
        kids = [c for c in range(len(nodes)) if nodes[c].parent == k]
        if kids:
            child_members = [i for c in kids for i in nodes[c].members]
            node.reference = node.members[int(np.argmin(mean[np.ix_(node.members, child_members)].mean(axis=1)))]
    return Hierarchy(nodes)


def _rigid_groups(rig: np.ndarray, idx: list[int], max_group: int, linkage, fcluster) -> np.ndarray:
    """Cluster labels over ``idx`` by average linkage on rigidity, groups capped at ``max_group``."""
    if len(idx) == 1:
        return np.zeros(1, dtype=np.int64)
    sub = rig[np.ix_(idx, idx)]
    cond = sub[np.triu_indices(len(idx), 1)]
    z = linkage(cond, method="average")
    for k in range(max(1, -(-len(idx) // max_group)), len(idx) + 1):
        lab = fcluster(z, k, criterion="maxclust")
        if np.bincount(lab).max() <= max_group:
            return lab
    return np.arange(len(idx))


# ------------------------------------------------------------------ skeletons
def build_skeleton_hierarchy(skeleton: Skeleton) -> Hierarchy:
    """Body parts of a joint tree: the root joint, spine + head, then each arm and each leg.

    The root joint's child subtrees are the candidate parts; the largest one (the spine) is followed to
    its first branching joint with two or more non-trivial branches (the chest): the chest's largest
    branches become the arms, the rest (neck, head) stays with the spine. Joints without channels are
    left out (they carry no data).
    """
    parents = skeleton.parents
    n = skeleton.n_joints
    has = [len(c) > 0 for c in skeleton.channels]
    kids = [[int(c) for c in np.flatnonzero(parents == j)] for j in range(n)]

    def subtree(j: int) -> list[int]:
        out, stack = [], [j]
        while stack:
            k = stack.pop()
            out.append(k)
            stack.extend(reversed(kids[k]))
        return sorted(out)

    root = int(np.flatnonzero(parents < 0)[0])
    parts: list[tuple[str, list[int], str]] = []
    branches = sorted(kids[root], key=lambda c: -len(subtree(c)))
    if branches:
        spine_top = branches[0]
        chain = [spine_top]
        j = spine_top
        while True:
            big = [c for c in kids[j] if len(subtree(c)) >= 2]
            if len(big) >= 2 or not kids[j]:
                break
            j = kids[j][0] if len(kids[j]) == 1 else max(kids[j], key=lambda c: len(subtree(c)))
            chain.append(j)
        chest = chain[-1]
        sub = sorted(kids[chest], key=lambda c: -len(subtree(c)))
        limbs = sub[:2] if len(sub) >= 3 else []
        spine = [k for k in subtree(spine_top) if not any(k in subtree(a) for a in limbs)]
        parts.append(("spine", spine, "root"))
        for a in sorted(limbs):
            parts.append((f"arm{len(parts)}", subtree(a), "spine"))
        for b in sorted(branches[1:]):
            parts.append((f"leg{len(parts)}", subtree(b), "root"))
    nodes = [Node("root", [root], -1, root)]
    for name, mem, parent in parts:
        mem = [k for k in mem if has[k]]
        if mem:
            pidx = next((i for i, nd in enumerate(nodes) if nd.name == parent), 0)
            nodes.append(Node(name, mem, pidx, mem[0]))
    return Hierarchy(nodes)
