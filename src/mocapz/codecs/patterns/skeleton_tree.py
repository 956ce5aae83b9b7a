"""Automatic hierarchy for skeletons: the root joint, spine + head, each arm, each leg."""

from __future__ import annotations

import numpy as np

from mocapz.codecs.patterns.hierarchy import Hierarchy, Node, topological
from mocapz.model.skeleton import Skeleton


def build_skeleton_hierarchy(skeleton: Skeleton) -> Hierarchy:
    """Body parts of a joint tree: the root joint, spine + head, then each arm and each leg.

    From the root joint the tree is followed down single-child chains to the pelvis (the first joint
    with two or more branches). The pelvis's largest branch is the spine: it is followed to the chest
    (the first joint with three or more branches, or two big ones), whose two largest branches are the
    arms; everything else on the spine (neck, head, the chain down to the root) forms the spine node. The
    pelvis's other branches are the legs (a branch holding both legs is split at its own fork). Joints
    without channels are left out (they carry no data).
    """
    parents = skeleton.parents
    n = skeleton.n_joints
    has = [len(c) > 0 for c in skeleton.channels]
    kids = [[int(c) for c in np.flatnonzero(parents == j)] for j in range(n)]
    size = np.ones(n, dtype=np.int64)
    for j in range(n - 1, 0, -1):
        if parents[j] >= 0:
            size[parents[j]] += size[j]

    def subtree(j: int) -> list[int]:
        out, stack = [], [j]
        while stack:
            k = stack.pop()
            out.append(k)
            stack.extend(kids[k])
        return sorted(out)

    def descend(j: int, branches: int) -> tuple[list[int], int | None]:
        """Chain from ``j`` down to the first joint with ``branches`` or more big branches."""
        chain = []
        while True:
            chain.append(j)
            big = [c for c in kids[j] if size[c] >= 2]
            if len(big) >= branches or (branches > 2 and len(kids[j]) >= branches and len(big) >= 2):
                return chain, j
            if not kids[j]:
                return chain, None
            j = max(kids[j], key=lambda c: size[c])

    root = int(np.flatnonzero(parents < 0)[0])
    parts: list[tuple[str, list[int]]] = []
    if kids[root]:
        chain, pelvis = descend(root, 2)
        pre = chain[1:]
        if pelvis is None:
            parts.append(("spine", pre))
        else:
            branches = sorted(kids[pelvis], key=lambda c: -size[c])
            spine_chain, chest = descend(branches[0], 3)
            limbs = sorted(kids[chest], key=lambda c: -size[c])[:2] if chest is not None else []
            in_limbs = {k for a in limbs for k in subtree(a)}
            spine = pre + [k for k in subtree(branches[0]) if k not in in_limbs]
            parts.append(("spine", sorted(set(spine))))
            for a in sorted(limbs):
                parts.append((f"arm{len(parts)}", subtree(a)))
            for b in sorted(branches[1:]):
                parts.extend(_legs(b, descend, subtree, size, kids, len(parts)))
    nodes = [Node("root", [root], -1, root)]
    for name, mem in parts:
        mem = [k for k in mem if has[k]]
        if mem:
            nodes.append(Node(name, mem, 0, mem[0]))
    spine_index = next((i for i, nd in enumerate(nodes) if nd.name == "spine"), 0)
    count = {"arm": 0, "leg": 0}
    for nd in nodes[1:]:
        kind = nd.name[:3]
        if kind in count:
            count[kind] += 1
            nd.name = f"{kind}{count[kind]}"
        if kind == "arm":
            nd.parent = spine_index
    return topological(nodes)


def _legs(top: int, descend, subtree, size, kids, start: int) -> list[tuple[str, list[int]]]:
    """One part per leg below ``top`` (split at the fork if the branch holds several legs)."""
    chain, fork = descend(top, 2)
    if fork is None or size[top] < 4:
        return [(f"leg{start}", subtree(top))]
    bigs = sorted((c for c in kids[fork] if size[c] >= 2), key=lambda c: c)
    rest = [k for k in subtree(top) if not any(k in subtree(b) for b in bigs)]
    out = [(f"leg{start + i}", subtree(b)) for i, b in enumerate(bigs)]
    out[0] = (out[0][0], sorted(rest + out[0][1]))
    return out
