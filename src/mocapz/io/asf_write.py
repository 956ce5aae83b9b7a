"""ASF text for a skeleton being written next to an AMC file.

A skeleton read from ASF is written back verbatim (its ASF text is kept in ``skeleton.extra``) as long
as it still matches that text; any other skeleton (e.g. from BVH) gets a generated ASF whose forward
kinematics reproduces every joint and end-site position of the skeleton exactly. Lengths are written in
the skeleton's file units (``:units length`` is 2.54 / ``unit_cm``, or 1 when the unit is unknown),
angles in degrees. The AMC file itself is written by :mod:`mocapz.io.amc`.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mocapz.errors import FormatError, MocapzError
from mocapz.io.asf import CHANNEL_DOF, build_skeleton, parse_asf_text
from mocapz.model.skeleton import Skeleton

_BAD_NAME = re.compile(r"[\s#(),]")


# ---------------------------------------------------------------------------- the ASF to write
def asf_for(sk: Skeleton, asf_path: Path) -> tuple[str, dict[str, tuple[int, tuple[str, ...]]]]:
    """ASF text to write, and per AMC bone (in line order) its motion joint and channels in column order."""
    text = sk.extra.get("asf_text")
    bones = sk.extra.get("amc_bones")
    if isinstance(text, str) and bones is not None:
        try:
            ref = build_skeleton(parse_asf_text(text, asf_path), list(bones))
        except (FormatError, KeyError):
            ref = None
        if ref is not None and _same_skeleton(ref, sk):
            index = {n: j for j, n in enumerate(sk.names)}
            return text, {b: (index[b], sk.channels[index[b]]) for b in bones}
    text, joint_of_bone = generate_asf(sk)
    return text, {b: (j, _dof_order(sk, j)) for b, j in joint_of_bone.items()}


def _same_skeleton(a: Skeleton, b: Skeleton) -> bool:
    assert a.axis is not None and b.axis is not None
    if (a.names != b.names or list(a.channels) != list(b.channels) or a.rotation_order != b.rotation_order
            or len(a.end_sites) != len(b.end_sites)):
        return False
    if not (np.array_equal(a.parents, b.parents) and np.array_equal(a.offsets, b.offsets)
            and np.array_equal(a.axis, b.axis)):
        return False
    return all(ja == jb and np.array_equal(oa, ob)
               for (ja, oa, _), (jb, ob, _) in zip(a.end_sites, b.end_sites, strict=True))


def _dof_order(sk: Skeleton, j: int) -> tuple[str, ...]:
    """ASF dof order for joint ``j``: positions as listed, then rotations in application order."""
    pos = tuple(c for c in sk.channels[j] if c.endswith("position"))
    return pos + tuple(f"{a}rotation" for a in reversed(sk.rotation_order[j]))


# ---------------------------------------------------------------------------- ASF generation
def _num(v: float) -> str:
    v = float(v)
    if v == 0:
        return "0"
    text = repr(v)
    return text[:-2] if text.endswith(".0") else text


@dataclass
class _Spec:
    """A bone to emit: its name, parent bone, base-to-tip vector, axis matrix and dofs."""

    name: str
    parent: str
    vector: np.ndarray
    axis: np.ndarray
    dofs: tuple[str, ...]


def generate_asf(sk: Skeleton) -> tuple[str, dict[str, int]]:
    """ASF text for any skeleton, exact for FK, and the motion joint of every bone with dofs.

    Every joint becomes a bone of the same name (the root becomes ``root``). ASF children all sit at
    their parent's tip, so a joint's tip is the offset most of its children share (a leaf: its first end
    site; zero if a child has position channels, which replace offsets). A child at another offset is
    hung from a dof-less bone ``<child>_dum`` spanning tip -> offset, and further end sites become
    dof-less leaf bones ``<joint>_End<k>``; these extra bones add points but leave all joint and end-site
    positions of the original skeleton unchanged.
    """
    roots = np.flatnonzero(sk.parents < 0)
    if roots.size != 1:
        raise MocapzError(f"an ASF skeleton needs exactly one root joint, this one has {roots.size}")
    _check_names(sk)
    assert sk.axis is not None
    ends: dict[int, list[np.ndarray]] = {}
    for j, off, _ in sk.end_sites:
        ends.setdefault(j, []).append(np.asarray(off, dtype=np.float64))
    root = int(roots[0])
    bone_name = {root: "root"}
    used = set(sk.names) | {"root"}
    specs: list[_Spec] = []
    for j in range(sk.n_joints):
        if j not in bone_name:
            continue  # unreachable: parents precede children
        tip = np.zeros(3) if j == root else _tip(sk, j, ends.get(j, []))
        if j != root:
            specs[_spec_index(specs, bone_name[j])].vector = tip
        _emit_children(sk, j, tip, bone_name, used, specs)
        _emit_end_dummies(sk, j, tip, ends.get(j, []), bone_name[j], used, specs)
    joint_of_bone = {bone_name[j]: j for j in range(sk.n_joints) if sk.channels[j]}
    return _asf_text(sk, root, specs), joint_of_bone


def _check_names(sk: Skeleton) -> None:
    for j, n in enumerate(sk.names):
        if not n or _BAD_NAME.search(n) or n.startswith(":"):
            raise MocapzError(f"joint name {n!r} cannot be written to an ASF file (spaces, #, (), commas)")
        if n == "root" and sk.parents[j] >= 0:
            raise MocapzError("a non-root joint named 'root' cannot be written to an ASF file")


def _spec_index(specs: list[_Spec], name: str) -> int:
    for k in range(len(specs) - 1, -1, -1):
        if specs[k].name == name:
            return k
    raise KeyError(name)


def _tip(sk: Skeleton, j: int, end_offsets: list[np.ndarray]) -> np.ndarray:
    kids = sk.children(j)
    if any(_has_positions(sk, c) for c in kids):
        return np.zeros(3)
    if not kids:
        return end_offsets[0].copy() if end_offsets else np.zeros(3)
    offs = [tuple(sk.offsets[c].tolist()) for c in kids]
    best = max(offs, key=offs.count)  # first of the most common offsets
    return np.array(best)


def _has_positions(sk: Skeleton, j: int) -> bool:
    return any(c.endswith("position") for c in sk.channels[j])


def _unique(name: str, used: set[str]) -> str:
    out, k = name, 2
    while out in used:
        out, k = f"{name}{k}", k + 1
    used.add(out)
    return out


def _emit_children(sk: Skeleton, j: int, tip: np.ndarray, bone_name: dict[int, str], used: set[str],
                   specs: list[_Spec]) -> None:
    parent = bone_name[j]
    assert sk.axis is not None
    for c in sk.children(j):
        off = sk.offsets[c]
        if not _has_positions(sk, c) and not np.array_equal(off, tip):
            dummy = _unique(f"{sk.names[c]}_dum", used)
            specs.append(_Spec(dummy, parent, off - tip, np.eye(3), ()))
            parent_c = dummy
        else:
            parent_c = parent
        bone_name[c] = sk.names[c]
        dofs = tuple(CHANNEL_DOF[ch] for ch in _dof_order(sk, c))
        specs.append(_Spec(sk.names[c], parent_c, np.zeros(3), sk.axis[c], dofs))


def _emit_end_dummies(sk: Skeleton, j: int, tip: np.ndarray, end_offsets: list[np.ndarray], name: str,
                      used: set[str], specs: list[_Spec]) -> None:
    """End sites other than the tip of a leaf become dof-less leaf bones."""
    leaf = not sk.children(j)
    for k, off in enumerate(end_offsets):
        if leaf and k == 0 and j != int(np.flatnonzero(sk.parents < 0)[0]):
            continue
        dummy = _unique(f"{name}_End{k + 1}", used)
        specs.append(_Spec(dummy, name, off - tip, np.eye(3), ()))


def _axis_text(axis: np.ndarray) -> str:
    if np.array_equal(axis, np.eye(3)):
        return "0 0 0 XYZ"
    with warnings.catch_warnings():  # gimbal lock (e.g. axis -90 90 0) still gives the same matrix
        warnings.simplefilter("ignore", UserWarning)
        from scipy.spatial.transform import Rotation  # noqa: I001 (on use: scipy loads slowly)
        angles = Rotation.from_matrix(axis).as_euler("xyz", degrees=True)
    return " ".join(_num(a) for a in angles) + " XYZ"


def _asf_text(sk: Skeleton, root: int, specs: list[_Spec]) -> str:
    assert sk.axis is not None
    length = 2.54 / sk.unit_cm if sk.unit_cm else 1.0
    root_dofs = " ".join(CHANNEL_DOF[c].upper() for c in _dof_order(sk, root))
    out = [
        "# Acclaim skeleton file written by mocapz",
        ":version 1.10", f":name {sk.extra.get('asf_name') or 'mocapz'}",
        ":units", "  mass 1.0", f"  length {_num(length)}", "  angle deg",
        ":documentation", f"  generated from a {len(sk.names)}-joint skeleton ({sk.unit_note})",
        ":root", f"  order {root_dofs}", "  axis " + _axis_text(sk.axis[root]).split()[-1],
        "  position " + " ".join(_num(v) for v in sk.offsets[root]),
        "  orientation " + " ".join(_axis_text(sk.axis[root]).split()[:3]),
        ":bonedata",
    ]
    for k, s in enumerate(specs, start=1):
        out.extend(_bone_lines(k, s))
    out.extend([":hierarchy", "  begin"])
    kids: dict[str, list[str]] = {}
    for s in specs:
        kids.setdefault(s.parent, []).append(s.name)
    for parent, names in kids.items():
        out.append(f"    {parent} {' '.join(names)}")
    out.append("  end")
    return "\n".join(out) + "\n"


def _bone_lines(k: int, s: _Spec) -> list[str]:
    length = float(np.linalg.norm(s.vector))
    direction = s.vector / length if length > 0 else np.array([0.0, 0.0, 1.0])
    lines = ["  begin", f"    id {k}", f"    name {s.name}",
             "    direction " + " ".join(_num(v) for v in direction),
             f"    length {_num(length)}", f"    axis {_axis_text(s.axis)}"]
    if s.dofs:
        lines.append("    dof " + " ".join(s.dofs))
    lines.append("  end")
    return lines
