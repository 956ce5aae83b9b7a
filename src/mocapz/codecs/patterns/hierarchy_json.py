"""A hierarchy given by the user as a small JSON file.

Format (marker names for marker data, joint names for skeletons)::

    {"nodes": [
        {"name": "root",  "markers": ["C7"]},
        {"name": "head",  "parent": "root", "markers": ["LFHD", "RFHD", "LBHD", "RBHD"]},
        {"name": "larm",  "parent": "root", "markers": ["LSHO", "LUPA", "LELB"], "reference": "LELB"},
        ...
    ]}

Exactly one node has no ``parent``: the root, with exactly one member (the root marker / root joint).
``"joints"`` may be used instead of ``"markers"``. ``reference`` (the member children are relative to)
defaults to the first member. Members not listed are attached automatically (markers: to the node of their
most rigid neighbour; joints: to the node of their nearest listed ancestor).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.codecs.patterns.hierarchy import Hierarchy, Node, topological
from mocapz.codecs.patterns.marker_tree import attach_by_rigidity
from mocapz.errors import OptionError


def _fail(path: Path, problem: str) -> OptionError:
    return OptionError(f"{path}: hierarchy: {problem}")


def read_hierarchy_json(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """Parse and structurally check the JSON file; returns its node list."""
    p = Path(path)
    if not p.is_file():
        raise _fail(p, "no such file")
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise _fail(p, f"not valid JSON ({exc})") from None
    nodes = doc.get("nodes") if isinstance(doc, dict) else None
    if not isinstance(nodes, list) or not nodes:
        raise _fail(p, 'expected an object with a non-empty "nodes" list')
    names: set[str] = set()
    for k, nd in enumerate(nodes):
        if not isinstance(nd, dict) or not isinstance(nd.get("name"), str):
            raise _fail(p, f"node #{k + 1} must be an object with a string \"name\"")
        mem = nd.get("markers", nd.get("joints"))
        if not isinstance(mem, list) or not mem or not all(isinstance(x, str) for x in mem):
            raise _fail(p, f"node {nd['name']!r} needs a non-empty list of member names (\"markers\")")
        if nd["name"] in names:
            raise _fail(p, f"node name {nd['name']!r} is used twice")
        names.add(nd["name"])
        if "parent" in nd and nd["parent"] is not None and not isinstance(nd["parent"], str):
            raise _fail(p, f"node {nd['name']!r}: \"parent\" must be a node name")
        if "reference" in nd and nd["reference"] not in mem:
            raise _fail(p, f"node {nd['name']!r}: reference {nd['reference']!r} is not one of its members")
    roots = [nd for nd in nodes if nd.get("parent") is None]
    if len(roots) != 1:
        raise _fail(p, f"exactly one node must have no parent (found {len(roots)})")
    if len(roots[0].get("markers", roots[0].get("joints"))) != 1:
        raise _fail(p, "the root node must hold exactly one member (the root marker / joint)")
    for nd in nodes:
        if nd.get("parent") is not None and nd["parent"] not in names:
            raise _fail(p, f"node {nd['name']!r}: unknown parent {nd['parent']!r}")
    return nodes


def hierarchy_from_json(path: str | os.PathLike[str], member_names: list[str],
                        positions: np.ndarray | None = None, parents: np.ndarray | None = None) -> Hierarchy:
    """Build a :class:`Hierarchy` from a JSON file for the given marker labels or joint names.

    Args:
        path: the JSON file.
        member_names: marker labels (marker data) or joint names (skeleton).
        positions: ``(frames, markers, 3)`` marker positions (to attach unlisted markers), or ``None``.
        parents: joint parent indices (skeletons, to attach unlisted joints), or ``None``.
    """
    p = Path(path)
    spec = read_hierarchy_json(p)
    index = {name: i for i, name in enumerate(member_names)}
    order = [next(nd for nd in spec if nd.get("parent") is None)]
    order += [nd for nd in spec if nd.get("parent") is not None]
    node_index = {nd["name"]: k for k, nd in enumerate(order)}
    nodes, used = [], set()
    for nd in order:
        mem = []
        for name in nd.get("markers", nd.get("joints")):
            if name not in index:
                raise _fail(p, f"node {nd['name']!r}: unknown member {name!r} (not in this file)")
            if index[name] in used:
                raise _fail(p, f"member {name!r} appears in more than one node")
            used.add(index[name])
            mem.append(index[name])
        ref = index[nd.get("reference", nd.get("markers", nd.get("joints"))[0])]
        parent = -1 if nd.get("parent") is None else node_index[nd["parent"]]
        nodes.append(Node(nd["name"], mem, parent, ref))
    try:
        hier = topological(nodes)
    except Exception as exc:  # noqa: BLE001 - a cycle between named parents
        raise _fail(p, str(exc).removeprefix("hierarchy: ")) from None
    rest = [i for i in range(len(member_names)) if i not in used]
    if rest:
        _attach_rest(hier, rest, positions, parents)
    return hier


def _attach_rest(hier: Hierarchy, rest: list[int], positions: np.ndarray | None,
                 parents: np.ndarray | None) -> None:
    owner = {m: k for k, n in enumerate(hier.nodes) for m in n.members}
    if parents is not None:
        for j in sorted(rest):
            a = int(parents[j])
            while a >= 0 and a not in owner:
                a = int(parents[a])
            k = owner.get(a, 0)
            if k == 0:
                hier.nodes.append(Node(f"extra{j}", [j], 0, j))
                k = len(hier.nodes) - 1
            else:
                hier.nodes[k].members.append(j)
            owner[j] = k
        return
    assert positions is not None
    for u, k in attach_by_rigidity(rest, owner, positions).items():
        if k <= 0:
            hier.nodes.append(Node(f"extra{u}", [u], 0, u))
        else:
            hier.nodes[k].members.append(u)
