"""Body-part hierarchy (paper §III.A): nodes of markers (or joints), each relative to its parent.

A :class:`Hierarchy` is a list of :class:`Node` in topological order (parents first); ``nodes[0]`` is the
root node, holding the single root marker (the one behind the top of the spine, C7) whose absolute
positions are coded per frame. Every other node's members are coded relative to the *reference* member
of its parent node (the member near the joint with the children).

Hierarchies are built automatically (:mod:`.marker_tree` from standard CMU / Vicon marker names and, for
unknown names, from the markers' rigidity and proximity; :mod:`.skeleton_tree` from the joint tree), or
read from a small JSON file (:mod:`.hierarchy_json`). They are stored in the stream with
:meth:`Hierarchy.to_bytes`.
"""

from __future__ import annotations

from dataclasses import dataclass

from mocapz.errors import FormatError, MocapzError
from mocapz.format.entropy import read_uvarint, write_uvarint


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
    def from_bytes(cls, data: bytes, n_members: int | None = None) -> Hierarchy:
        """Inverse of :meth:`to_bytes`; with ``n_members`` (the clip's marker or joint count) the hierarchy is
        also checked against it (:meth:`validate`). Damage is a FormatError."""
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
        hier = cls(nodes)
        if n_members is not None:
            try:
                hier.validate(n_members)
            except MocapzError as exc:
                raise FormatError(None, f"corrupted pattern hierarchy ({exc.message.removeprefix('hierarchy: ')})") \
                    from None
        return hier


def topological(nodes: list[Node]) -> Hierarchy:
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
