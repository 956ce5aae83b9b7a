"""Acclaim ASF skeleton files: find the ASF of an AMC, parse it, and map it onto a Skeleton.

The ASF bones map onto the generic :class:`~mocapz.model.skeleton.Skeleton`:

* one joint per ASF bone, placed at the bone's base (``root`` included, first); the joint order is a
  depth-first walk of ``:hierarchy``;
* the offset of a bone's joint is its parent bone's ``direction * length`` (zero for children of
  ``root``); the root's offset is the ``:root position``;
* ``axis[j]`` is the rotation matrix of the bone's ASF ``axis`` (root: ``orientation``), so the local
  rotation is ``C @ M @ C.T`` with ``M`` built from the AMC values, as in the Acclaim definition;
* a bone's channels are its ``dof`` entries in AMC column order (``rx`` -> ``Xrotation``, ``tx`` ->
  ``Xposition``). Acclaim rotations are applied about fixed axes in the order the dofs are listed, so
  ``dof rx ry rz`` gives ``M = Rz @ Ry @ Rx`` and ``rotation_order`` is the reversed dof order (``"ZYX"``);
  this reproduces the CMU cgspeed BVH conversion to float precision;
* the tip of every leaf bone is an end site named ``<bone>_End``.

Lengths stay in file units (``:units length``, with ``unit_cm`` the centimetres per unit), angles in
the ASF angle unit (``deg`` or ``rad``). The motion values come from the AMC file (:mod:`mocapz.io.amc`);
writing an ASF is :mod:`mocapz.io.asf_write`.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocapz.errors import FormatError
from mocapz.io.common import guess_unit_cm, read_text, rest_height
from mocapz.model.skeleton import Skeleton

DOF_CHANNEL = {
    "tx": "Xposition", "ty": "Yposition", "tz": "Zposition",
    "rx": "Xrotation", "ry": "Yrotation", "rz": "Zrotation",
}
CHANNEL_DOF = {v: k for k, v in DOF_CHANNEL.items()}

_COMMENT = re.compile(r"(^|\s)#.*")
_SEPARATORS = str.maketrans({",": " ", "(": " ", ")": " "})  # the ASF definition treats these as spaces


# ============================================================================ ASF model
@dataclass
class AsfBone:
    """One ASF bone (or the root, with zero vector). Angles in the ASF angle unit."""

    name: str
    direction: np.ndarray  # (3,)
    length: float
    axis: np.ndarray  # (3,) rotation angles about x, y, z
    axis_order: str  # e.g. "XYZ": the order the axis rotations are applied in
    dofs: tuple[str, ...]  # lower-case "rx", "tz", ... in AMC column order
    line: int

    @property
    def vector(self) -> np.ndarray:
        """Base-to-tip vector ``(3,)`` in file length units (global rest frame)."""
        return self.direction * self.length


@dataclass
class Asf:
    """A parsed ASF file."""

    path: Path
    text: str
    name: str = ""
    length_unit: float = 1.0
    angle_unit: str = "deg"
    root: AsfBone | None = None
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bones: dict[str, AsfBone] = field(default_factory=dict)
    children: dict[str, list[str]] = field(default_factory=dict)

    def order(self) -> list[str]:
        """Bone names in depth-first order from ``root`` (the skeleton's joint order)."""
        out: list[str] = []
        stack = ["root"]
        while stack:
            name = stack.pop()
            out.append(name)
            stack.extend(reversed(self.children.get(name, [])))
        return out

    def bone(self, name: str) -> AsfBone:
        assert self.root is not None
        return self.root if name == "root" else self.bones[name]


# ============================================================================ locating
def find_asf(amc: Path) -> Path:
    """The skeleton file of an AMC.

    ``<stem>.asf`` beside it, else the one ``.asf`` there whose stem starts the AMC's stem (CMU ``01.asf``
    for ``01_01.amc``; among several, those followed by a separator such as ``_``), else the folder's
    only ``.asf`` if no name matches. Anything else is a :class:`FormatError` naming the AMC.
    """
    folder = amc.parent if str(amc.parent) else Path(".")
    asfs = [p for p in folder.iterdir() if p.suffix.lower() == ".asf" and p.is_file()]
    stem = amc.stem.casefold()
    same = [p for p in asfs if p.stem.casefold() == stem]
    if len(same) == 1:
        return same[0]
    cands = [p for p in asfs if stem.startswith(p.stem.casefold())]
    if len(cands) > 1:  # prefer stems followed by a separator: 1.asf vs 11.asf for 11_01.amc
        cands = [p for p in cands if len(p.stem) < len(stem) and not stem[len(p.stem)].isalnum()]
    if len(cands) == 1:
        return cands[0]
    if not cands and len(asfs) == 1:  # e.g. skeleton.asf + walking.amc: the folder's only skeleton
        return asfs[0]
    found = ", ".join(sorted(p.name for p in cands)) if cands else "none"
    raise FormatError(
        amc,
        f"cannot tell which skeleton goes with this AMC: expected {amc.stem}.asf or one .asf whose name "
        f"starts {amc.stem!r} in {folder} (found {found}); pass the .asf explicitly",
    )


# ============================================================================ parsing
def parse_asf(path: str | os.PathLike[str]) -> Asf:
    """Parse an ASF file (units, root, bone data, hierarchy)."""
    path = Path(path)
    return parse_asf_text(read_text(path), path)


def parse_asf_text(text: str, path: Path) -> Asf:
    """Parse ASF text; ``path`` is only used in error messages."""
    sections = _asf_sections(text, path)
    asf = Asf(path=path, text=text)
    for key in ("root", "bonedata", "hierarchy"):
        if key not in sections:
            raise FormatError(path, f"not an ASF skeleton: no :{key} section", len(text.splitlines()))
    name = sections.get("name", [])
    asf.name = " ".join(name[0][1]) if name else ""
    _parse_units(asf, sections.get("units", []))
    _parse_root(asf, sections["root"])
    _parse_bonedata(asf, sections["bonedata"])
    _parse_hierarchy(asf, sections["hierarchy"])
    return asf


Lines = list[tuple[int, list[str]]]


def _asf_sections(text: str, path: Path) -> dict[str, Lines]:
    """Token lines per ``:section`` (comments dropped, ``,()`` as spaces, inline arguments kept)."""
    sections: dict[str, Lines] = {}
    current: Lines | None = None
    for i, raw in enumerate(text.splitlines(), start=1):
        toks = _COMMENT.sub("", raw).translate(_SEPARATORS).split()
        if not toks:
            continue
        if toks[0].startswith(":"):
            current = sections.setdefault(toks[0][1:].lower(), [])
            if len(toks) > 1:
                current.append((i, toks[1:]))
            continue
        if current is None:
            raise FormatError(path, f"not an ASF file: {raw.strip()[:40]!r} before any ':' keyword", i)
        current.append((i, toks))
    if not sections:
        raise FormatError(path, "not an ASF file: no ':' keywords")
    return sections


def _floats(toks: list[str], n: int, path: Path, line: int, what: str) -> np.ndarray:
    if len(toks) < n:
        raise FormatError(path, f"{what} needs {n} numbers, found {len(toks)}", line)
    try:
        vals = np.array([float(t) for t in toks[:n]])
    except ValueError:
        raise FormatError(path, f"bad number in {what}: {' '.join(toks[:n])!r}", line) from None
    if not np.isfinite(vals).all():
        raise FormatError(path, f"non-finite number in {what}", line)
    return vals


def _parse_units(asf: Asf, lines: Lines) -> None:
    for line, toks in lines:
        if len(toks) < 2:
            continue
        key, val = toks[0].lower(), toks[1]
        if key == "length":
            asf.length_unit = float(_floats([val], 1, asf.path, line, "units length")[0])
            if asf.length_unit <= 0:
                raise FormatError(asf.path, f"units length must be positive, got {val}", line)
        elif key == "angle":
            unit = val.lower()[:3]
            if unit not in ("deg", "rad"):
                raise FormatError(asf.path, f"unknown angle unit {val!r} (expected deg or rad)", line)
            asf.angle_unit = unit


def _axis_order(tok: str, path: Path, line: int) -> str:
    order = tok.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise FormatError(path, f"bad axis order {tok!r} (expected a permutation of XYZ)", line)
    return order


def _dofs(toks: list[str], path: Path, line: int, owner: str) -> tuple[str, ...]:
    dofs = tuple(t.lower() for t in toks)
    for d in dofs:
        if d == "l":
            raise FormatError(path, f"bone {owner}: length dof 'l' is not supported", line)
        if d not in DOF_CHANNEL:
            raise FormatError(path, f"bone {owner}: unknown dof {d!r}", line)
    if len(set(dofs)) != len(dofs):
        raise FormatError(path, f"bone {owner}: repeated dof in {' '.join(toks)!r}", line)
    return dofs


def _parse_root(asf: Asf, lines: Lines) -> None:
    order, orient = "XYZ", np.zeros(3)
    dofs: tuple[str, ...] = ()
    first = lines[0][0] if lines else 0
    for line, toks in lines:
        key = toks[0].lower()
        if key == "order":
            dofs = _dofs(toks[1:], asf.path, line, "root")
        elif key == "axis" and len(toks) > 1:
            order = _axis_order(toks[1], asf.path, line)
        elif key == "position":
            asf.position = _floats(toks[1:], 3, asf.path, line, "root position")
        elif key == "orientation":
            orient = _floats(toks[1:], 3, asf.path, line, "root orientation")
    # The pre-set orientation is used as the root's axis frame (C @ M @ C.T), like a bone's axis;
    # CMU/VICON files always set it to zero.
    asf.root = AsfBone("root", np.zeros(3), 0.0, orient, order, dofs, first)


def _parse_bonedata(asf: Asf, lines: Lines) -> None:
    block: Lines | None = None
    for line, toks in lines:
        word = toks[0].lower()
        if word == "begin":
            if block is not None:
                raise FormatError(asf.path, "'begin' inside a bone block (missing 'end'?)", line)
            block = []
        elif word == "end":
            if block is None:
                raise FormatError(asf.path, "'end' without 'begin' in :bonedata", line)
            bone = _parse_bone(asf, block, line)
            if bone.name in asf.bones or bone.name == "root":
                raise FormatError(asf.path, f"duplicate bone name {bone.name!r}", bone.line)
            asf.bones[bone.name] = bone
            block = None
        elif block is None:
            raise FormatError(asf.path, f"unexpected {toks[0]!r} outside a begin/end bone block", line)
        else:
            block.append((line, toks))
    if block is not None:
        raise FormatError(asf.path, "last bone block has no 'end' (truncated file?)", lines[-1][0])


def _parse_bone(asf: Asf, block: Lines, end_line: int) -> AsfBone:
    keys = {toks[0].lower(): (line, toks[1:]) for line, toks in block}
    if "name" not in keys or not keys["name"][1]:
        raise FormatError(asf.path, "bone block without a name", block[0][0] if block else end_line)
    name_line, name_toks = keys["name"]
    name = name_toks[0]
    for req in ("direction", "length"):
        if req not in keys:
            raise FormatError(asf.path, f"bone {name}: no {req}", name_line)
    direction = _floats(keys["direction"][1], 3, asf.path, keys["direction"][0], f"direction of {name}")
    length = float(_floats(keys["length"][1], 1, asf.path, keys["length"][0], f"length of {name}")[0])
    axis, order = np.zeros(3), "XYZ"
    if "axis" in keys:
        line, toks = keys["axis"]
        axis = _floats(toks, 3, asf.path, line, f"axis of {name}")
        order = _axis_order(toks[3], asf.path, line) if len(toks) > 3 else "XYZ"
    dofs = _dofs(keys["dof"][1], asf.path, keys["dof"][0], name) if "dof" in keys else ()
    return AsfBone(name, direction, length, axis, order, dofs, name_line)


def _parse_hierarchy(asf: Asf, lines: Lines) -> None:
    parent_of: dict[str, str] = {}
    for line, toks in lines:
        if toks[0].lower() in ("begin", "end"):
            continue
        parent = toks[0]
        for name in [parent, *toks[1:]]:
            if name != "root" and name not in asf.bones:
                raise FormatError(asf.path, f"hierarchy names bone {name!r}, which :bonedata lacks", line)
        for child in toks[1:]:
            if child == "root" or child in parent_of:
                raise FormatError(asf.path, f"bone {child!r} has two parents in :hierarchy", line)
            parent_of[child] = parent
            asf.children.setdefault(parent, []).append(child)
    reached = set(asf.order())
    loose = [n for n in asf.bones if n not in reached]
    if loose:
        raise FormatError(asf.path, f"bone {loose[0]!r} is not connected to root in :hierarchy",
                          asf.bones[loose[0]].line)


# ============================================================================ Skeleton mapping
def _axis_matrix(angles: np.ndarray, order: str, unit: str) -> np.ndarray:
    """Rotation ``(3, 3)`` of an ASF axis: rotations about x, y, z applied (fixed axes) in ``order``."""
    if not np.any(angles):
        return np.eye(3)
    vals = [angles["XYZ".index(a)] for a in order]
    from scipy.spatial.transform import Rotation  # noqa: I001 (on use: scipy loads slowly)
    return Rotation.from_euler(order.lower(), vals, degrees=unit == "deg").as_matrix()


def build_skeleton(asf: Asf, amc_bones: Iterable[str] | None = None) -> Skeleton:
    """Map a parsed ASF onto a :class:`Skeleton` (see the module docstring).

    Args:
        asf: the parsed skeleton.
        amc_bones: the bones the AMC frames list, in line order; bones with dofs that the AMC omits get
            no channels. ``None``: every bone with dofs, in skeleton order.
    """
    order = asf.order()
    index = {n: j for j, n in enumerate(order)}
    present = set(amc_bones) if amc_bones is not None else {n for n in order if asf.bone(n).dofs}
    parents, offsets, channels, rot_orders, axes, ends = [], [], [], [], [], []
    parent_of = {c: p for p, cs in asf.children.items() for c in cs}
    for name in order:
        bone = asf.bone(name)
        parent = parent_of.get(name)
        parents.append(-1 if parent is None else index[parent])
        offsets.append(asf.position if parent is None else asf.bone(parent).vector)
        dofs = bone.dofs if name in present else ()
        channels.append(tuple(DOF_CHANNEL[d] for d in dofs))
        rot_orders.append("".join(d[1].upper() for d in reversed(dofs) if d[0] == "r"))
        axes.append(_axis_matrix(bone.axis, bone.axis_order, asf.angle_unit))
        if name != "root" and not asf.children.get(name):
            ends.append((index[name], bone.vector.copy(), f"{name}_End"))
    sk = Skeleton(
        names=order, parents=np.array(parents), offsets=np.array(offsets), channels=channels,
        rotation_order=rot_orders, axis=np.array(axes), end_sites=ends, angle_unit=asf.angle_unit,
        extra={"asf_text": asf.text, "asf_name": asf.name,
               "amc_bones": list(amc_bones) if amc_bones is not None else [n for n in order if n in present]},
    )
    sk.unit_cm, sk.unit_note = _units(asf, sk)
    return sk


def _units(asf: Asf, sk: Skeleton) -> tuple[float | None, str]:
    """Centimetres per unit: the CMU reading ``2.54 / length`` if it gives a human-sized skeleton."""
    height = rest_height(sk)
    cm = 2.54 / asf.length_unit
    if 50.0 <= height * cm <= 300.0:
        return cm, (f"ASF :units length {asf.length_unit:g}: 1 unit = 2.54/{asf.length_unit:g} cm "
                    f"= {cm:.4g} cm (CMU convention; rest skeleton {height * cm:.0f} cm)")
    guess, note = guess_unit_cm(height)
    return guess, (f"ASF :units length {asf.length_unit:g} read as 2.54/length cm per unit would make the "
                   f"rest skeleton {height * cm:.0f} cm; {note}")
