"""Acclaim ASF/AMC reader and writer.

The ASF (skeleton) and AMC (motion) pair maps onto the generic :class:`~mocapz.model.skeleton.Skeleton`:

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

Channel values stay as in the file (degrees for ``:DEGREES``). Translation dofs of non-root bones
replace the joint's offset (the project's BVH convention); root translations are absolute.
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mocapz.errors import FormatError, MocapzError
from mocapz.io.common import atomic_write, detect_decimals, guess_unit_cm, read_text
from mocapz.model.motion import Motion
from mocapz.model.skeleton import Skeleton

DEFAULT_FRAME_RATE = 120.0  # CMU capture rate; the AMC format has no rate field

DOF_CHANNEL = {
    "tx": "Xposition", "ty": "Yposition", "tz": "Zposition",
    "rx": "Xrotation", "ry": "Yrotation", "rz": "Zrotation",
}
CHANNEL_DOF = {v: k for k, v in DOF_CHANNEL.items()}

_COMMENT = re.compile(r"(^|\s)#.*")
_SEPARATORS = str.maketrans({",": " ", "(": " ", ")": " "})  # the ASF definition treats these as spaces
_BAD_NAME = re.compile(r"[\s#(),]")


# ============================================================================ ASF model
@dataclass
class _Bone:
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
class _Asf:
    """A parsed ASF file."""

    path: Path
    text: str
    name: str = ""
    length_unit: float = 1.0
    angle_unit: str = "deg"
    root: _Bone | None = None
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bones: dict[str, _Bone] = field(default_factory=dict)
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

    def bone(self, name: str) -> _Bone:
        assert self.root is not None
        return self.root if name == "root" else self.bones[name]


# ============================================================================ reading
def read_asfamc(
    amc: str | os.PathLike[str],
    asf: str | os.PathLike[str] | None = None,
    *,
    frame_rate: float = DEFAULT_FRAME_RATE,
) -> Motion:
    """Read an AMC motion and its ASF skeleton into a :class:`Motion`.

    Args:
        amc: the ``.amc`` file.
        asf: the ``.asf`` skeleton; by default found by :func:`find_asf` (``<stem>.asf`` beside the AMC,
            else the ``.asf`` whose stem starts the AMC's stem, else the folder's only ``.asf``).
        frame_rate: frames per second (AMC files do not store it; CMU captures at 120).

    Returns:
        A motion whose channels ``(frames, DOFs)`` hold the AMC values in file units and the AMC's
        angle unit, columns grouped per joint in skeleton (depth-first) order.
    """
    amc = Path(amc)
    amc_text = read_text(amc)
    asf_path = find_asf(amc) if asf is None else Path(asf)
    skel = parse_asf(asf_path)
    lines = amc_text.splitlines()
    header, start, angle = _amc_header(lines, amc, skel.angle_unit)
    dofs = {name: len(skel.bone(name).dofs) for name in skel.order()}
    bones, data, first = _parse_amc_frames(lines, start, amc, dofs)
    sk = build_skeleton(skel, bones)
    sk.angle_unit = angle
    channels = data[:, _amc_to_skeleton_columns(sk, bones, skel)]
    return Motion(
        skeleton=sk,
        channels=channels,
        frame_rate=float(frame_rate),
        name=amc.stem,
        source_format="asfamc",
        decimals=exact_decimals(channels),
        metadata={
            "path": str(amc),
            "asf_path": str(asf_path),
            "file_bytes": amc.stat().st_size + asf_path.stat().st_size,
            "amc_header": header,
            "amc_first_frame": first,
        },
    )


def exact_decimals(channels: np.ndarray) -> np.ndarray | None:
    """Decimals per column ``(channels,)`` that reproduce every value exactly, else ``None``.

    AMC files write 6 significant digits (``%g``), so columns of tiny values such as ``3.64024e-015``
    need more decimals than :func:`detect_decimals` tries; it would call them 0 decimals, which is
    lossy. Such files get ``None`` (values then written with ``repr`` and coded as float64).
    """
    if not channels.size:
        return None
    dec = detect_decimals(channels)
    if dec is None:
        return None
    scale = 10.0 ** dec.astype(np.float64)
    exact = np.round(channels * scale) / scale == channels
    return dec if bool(exact.all()) else None


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


# ---------------------------------------------------------------------------- ASF
def parse_asf(path: str | os.PathLike[str]) -> _Asf:
    """Parse an ASF file (units, root, bone data, hierarchy)."""
    path = Path(path)
    return parse_asf_text(read_text(path), path)


def parse_asf_text(text: str, path: Path) -> _Asf:
    """Parse ASF text; ``path`` is only used in error messages."""
    sections = _asf_sections(text, path)
    asf = _Asf(path=path, text=text)
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


def _parse_units(asf: _Asf, lines: Lines) -> None:
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


def _parse_root(asf: _Asf, lines: Lines) -> None:
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
    asf.root = _Bone("root", np.zeros(3), 0.0, orient, order, dofs, first)


def _parse_bonedata(asf: _Asf, lines: Lines) -> None:
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


def _parse_bone(asf: _Asf, block: Lines, end_line: int) -> _Bone:
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
    return _Bone(name, direction, length, axis, order, dofs, name_line)


def _parse_hierarchy(asf: _Asf, lines: Lines) -> None:
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


# ---------------------------------------------------------------------------- skeleton
def _axis_matrix(angles: np.ndarray, order: str, unit: str) -> np.ndarray:
    """Rotation ``(3, 3)`` of an ASF axis: rotations about x, y, z applied (fixed axes) in ``order``."""
    if not np.any(angles):
        return np.eye(3)
    vals = [angles["XYZ".index(a)] for a in order]
    return Rotation.from_euler(order.lower(), vals, degrees=unit == "deg").as_matrix()


def build_skeleton(asf: _Asf, amc_bones: Iterable[str] | None = None) -> Skeleton:
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


def rest_height(sk: Skeleton) -> float:
    """Largest extent of the rest pose (all channels zero, offsets only), in file units."""
    from mocapz.model.kinematics import chain

    rot = np.broadcast_to(np.eye(3), (1, sk.n_joints, 3, 3)).copy()
    pos, _ = chain(sk, rot, sk.offsets[None].copy())
    return float(np.ptp(pos[0], axis=0).max())


def _units(asf: _Asf, sk: Skeleton) -> tuple[float | None, str]:
    """Centimetres per unit: the CMU reading ``2.54 / length`` if it gives a human-sized skeleton."""
    height = rest_height(sk)
    cm = 2.54 / asf.length_unit
    if 50.0 <= height * cm <= 300.0:
        return cm, (f"ASF :units length {asf.length_unit:g}: 1 unit = 2.54/{asf.length_unit:g} cm "
                    f"= {cm:.4g} cm (CMU convention; rest skeleton {height * cm:.0f} cm)")
    guess, note = guess_unit_cm(height)
    return guess, (f"ASF :units length {asf.length_unit:g} read as 2.54/length cm per unit would make the "
                   f"rest skeleton {height * cm:.0f} cm; {note}")


# ---------------------------------------------------------------------------- AMC
def _amc_header(lines: list[str], path: Path, default_angle: str) -> tuple[list[str], int, str]:
    """Header comment lines, index of the first frame-number line, and the angle unit of the values."""
    angle, header = default_angle, []
    for i, raw in enumerate(lines):
        s = raw.strip()
        if not s:
            continue
        if s.startswith("#"):
            header.append(s)
        elif s.startswith(":"):
            key = s.split()[0].upper()
            if key in (":DEGREES", ":RADIANS"):
                angle = "deg" if key == ":DEGREES" else "rad"
            elif key != ":FULLY-SPECIFIED":
                header.append(s)
        elif s.isdigit():
            return header, i, angle
        else:
            raise FormatError(path, f"expected a frame number, found {s[:40]!r}", i + 1)
    raise FormatError(path, "no frames (no frame-number line after the header)", len(lines))


def _parse_amc_frames(
    lines: list[str], start: int, path: Path, dofs: dict[str, int]
) -> tuple[list[str], np.ndarray, int]:
    """Parse the frame records.

    Returns:
        the bones of a frame in the first frame's line order, the values ``(frames, DOFs)`` in that
        column order, and the first frame number.
    """
    tokens: list[str] = []
    frame_lines: list[int] = []
    frame_nos: list[int] = []
    permuted: dict[int, tuple[str, ...]] = {}
    first: list[str] | None = None
    cur: list[str] = []
    cur_lines: list[int] = []

    def close() -> None:
        nonlocal first
        if first is None:
            _check_unique(cur, cur_lines, frame_lines[-1], path)
            first = list(cur)
        elif cur != first:
            _check_same_bones(first, cur, cur_lines, frame_lines[-1], frame_nos[-1], path)
            permuted[len(frame_nos) - 1] = tuple(cur)

    for i in range(start, len(lines)):
        parts = lines[i].split()
        if not parts or parts[0][0] == "#":
            continue
        head = parts[0]
        if len(parts) == 1 and head.isdigit():
            if frame_nos:
                close()
            frame_nos.append(int(head))
            frame_lines.append(i + 1)
            cur, cur_lines = [], []
            continue
        n = dofs.get(head)
        if n is None:
            raise FormatError(path, f"bone {head!r} is not in the ASF skeleton", i + 1)
        if len(parts) - 1 != n:
            raise FormatError(path, f"bone {head!r} has {len(parts) - 1} values, its ASF dofs are {n}", i + 1)
        cur.append(head)
        cur_lines.append(i + 1)
        tokens.extend(parts[1:])
    close()
    assert first is not None
    _check_frame_numbers(frame_nos, frame_lines, path)
    data = _to_floats(tokens, lines, start, path).reshape(len(frame_nos), -1)
    _check_finite(data, frame_lines, path)
    _unpermute(data, first, permuted, dofs)
    return first, data, frame_nos[0]


def _check_unique(bones: list[str], lines: list[int], frame_line: int, path: Path) -> None:
    seen: set[str] = set()
    for b, ln in zip(bones, lines, strict=True):
        if b in seen:
            raise FormatError(path, f"bone {b!r} appears twice in one frame", ln)
        seen.add(b)
    if not bones:
        raise FormatError(path, "first frame has no bone lines", frame_line)


def _check_same_bones(
    first: list[str], cur: list[str], cur_lines: list[int], frame_line: int, frame_no: int, path: Path
) -> None:
    ref = set(first)
    seen: set[str] = set()
    for b, ln in zip(cur, cur_lines, strict=True):
        if b not in ref:
            raise FormatError(path, f"frame {frame_no}: bone {b!r} is not in the first frame", ln)
        if b in seen:
            raise FormatError(path, f"frame {frame_no}: bone {b!r} appears twice", ln)
        seen.add(b)
    missing = [b for b in first if b not in seen]
    if missing:
        last = cur_lines[-1] if cur_lines else frame_line
        raise FormatError(
            path, f"frame {frame_no} is incomplete (truncated?): no line for {', '.join(missing[:5])}", last
        )


def _check_frame_numbers(frame_nos: list[int], frame_lines: list[int], path: Path) -> None:
    nos = np.asarray(frame_nos, dtype=np.int64)
    bad = np.flatnonzero(np.diff(nos) != 1)
    if bad.size:
        k = int(bad[0]) + 1
        raise FormatError(path, f"frame number {nos[k]} follows {nos[k - 1]} (frames must be consecutive)",
                          frame_lines[k])


def _to_floats(tokens: list[str], lines: list[str], start: int, path: Path) -> np.ndarray:
    try:
        return np.array(tokens, dtype=np.float64)
    except ValueError:
        for i in range(start, len(lines)):
            parts = lines[i].split()
            for t in parts[1:]:
                try:
                    float(t)
                except ValueError:
                    raise FormatError(path, f"non-numeric value {t!r} for bone {parts[0]!r}", i + 1) from None
        raise


def _check_finite(data: np.ndarray, frame_lines: list[int], path: Path) -> None:
    finite = np.isfinite(data)
    if finite.all():
        return
    f = int(np.flatnonzero(~finite.all(axis=1))[0])
    raise FormatError(path, "non-finite value (NaN/inf) in the frame record starting here", frame_lines[f])


def _unpermute(data: np.ndarray, first: list[str], permuted: dict[int, tuple[str, ...]],
               dofs: dict[str, int]) -> None:
    """Reorder the columns of frames whose bone lines came in another order than the first frame's."""
    if not permuted:
        return
    cache: dict[tuple[str, ...], np.ndarray] = {}
    for f, order in permuted.items():
        if order not in cache:
            cols = _bone_columns(list(order), dofs)
            cache[order] = np.concatenate([cols[b] for b in first])
        data[f] = data[f][cache[order]]


def _bone_columns(bones: list[str], dofs: dict[str, int]) -> dict[str, np.ndarray]:
    out, start = {}, 0
    for b in bones:
        out[b] = np.arange(start, start + dofs[b])
        start += dofs[b]
    return out


def _amc_to_skeleton_columns(sk: Skeleton, bones: list[str], asf: _Asf) -> np.ndarray:
    """For each skeleton column, its column in the AMC frame (bones in ``bones`` order)."""
    cols = _bone_columns(bones, {b: len(asf.bone(b).dofs) for b in bones})
    parts = [cols[name] for name, chs in zip(sk.names, sk.channels, strict=True) if chs]
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)


# ============================================================================ writing
def write_asfamc(motion: Motion, amc_path: str | os.PathLike[str], force: bool = False) -> list[Path]:
    """Write ``motion`` as an AMC file and its skeleton as ``<stem>.asf`` beside it.

    A skeleton read from ASF is written back verbatim (its ASF text is kept in ``skeleton.extra``);
    any other skeleton (e.g. from BVH) gets a generated ASF whose FK reproduces the motion's joint and
    end-site positions (see :func:`generate_asf`). Values are written at ``motion.decimals`` where known,
    else as the shortest text that reads back to the same float64. Both files are written atomically;
    existing files are kept unless ``force`` (an existing identical ASF is fine), and nothing is left
    behind on failure.

    Returns:
        ``[amc_path, asf_path]``.
    """
    amc_path = Path(amc_path)
    asf_path = amc_path.with_suffix(".asf")
    if amc_path.suffix.lower() != ".amc":
        raise MocapzError(f"{amc_path}: an AMC output needs the .amc extension")
    if not np.isfinite(motion.channels).all():
        raise FormatError(amc_path, "refusing to write non-finite channel values")
    asf_text, layout = _asf_for(motion.skeleton, asf_path)
    amc_text = _amc_text(motion, asf_path, layout)
    asf_is_same = asf_path.exists() and asf_path.read_bytes() == asf_text.encode("utf-8")
    if amc_path.exists() and not force:
        raise MocapzError(f"{amc_path}: output exists (use -f / force=True to overwrite)")
    if asf_path.exists() and not force and not asf_is_same:
        raise MocapzError(f"{asf_path}: a different skeleton file exists (use -f / force=True to overwrite)")
    old_asf = asf_path.read_bytes() if asf_path.exists() else None
    if not asf_is_same:
        _write_bytes(asf_path, asf_text.encode("utf-8"))
    try:
        atomic_write(amc_path, lambda tmp: tmp.write_bytes(amc_text.encode("utf-8")), force=force)
    except BaseException:
        if not asf_is_same:  # put the skeleton file back as it was
            if old_asf is None:
                asf_path.unlink(missing_ok=True)
            else:
                _write_bytes(asf_path, old_asf)
        raise
    return [amc_path, asf_path]


def _write_bytes(path: Path, data: bytes) -> None:
    atomic_write(path, lambda tmp: tmp.write_bytes(data), force=True)


def _asf_for(sk: Skeleton, asf_path: Path) -> tuple[str, dict[str, tuple[int, tuple[str, ...]]]]:
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


def _amc_text(motion: Motion, asf_path: Path, layout: dict[str, tuple[int, tuple[str, ...]]]) -> str:
    """The whole AMC file: header, then one record per frame, bones and columns as ``layout`` says."""
    sk = motion.skeleton
    slices = sk.channel_slices()
    cols: list[int] = []
    template = ["%d\n"]
    for j, chs in layout.values():
        cols.extend(slices[j].start + sk.channels[j].index(c) for c in chs)
    if sorted(cols) != list(range(sk.n_channels)):
        raise MocapzError("internal error: AMC columns do not cover the motion's channels")
    values = motion.channels[:, cols]
    dec = None if motion.decimals is None else np.asarray(motion.decimals, dtype=np.int64)[cols]
    fmts = iter(["%r"] * len(cols) if dec is None else [f"%.{int(d)}f" for d in dec])
    for bone, (_, chs) in layout.items():
        template.append(bone.replace("%", "%%") + "".join(" " + next(fmts) for _ in chs) + "\n")
    fmt = "".join(template)
    if dec is not None:  # avoid "-0.000" noise from values that round to zero
        values = np.where(np.abs(values) < 0.5 * 10.0 ** (-dec.astype(float)), 0.0, values)
    first = int(motion.metadata.get("amc_first_frame", 1))
    header = _amc_header_lines(motion, sk.angle_unit, asf_path)
    body = "".join(fmt % (first + f, *row) for f, row in enumerate(values.tolist()))
    return header + body


def _dof_order(sk: Skeleton, j: int) -> tuple[str, ...]:
    """ASF dof order for joint ``j``: positions as listed, then rotations in application order."""
    pos = tuple(c for c in sk.channels[j] if c.endswith("position"))
    return pos + tuple(f"{a}rotation" for a in reversed(sk.rotation_order[j]))


def _amc_header_lines(motion: Motion, angle_unit: str, asf_path: Path) -> str:
    kept = [h for h in motion.metadata.get("amc_header", []) if not h.upper().startswith("#!OML:ASF")]
    lines = [f"#!OML:ASF {asf_path.name}", *kept, ":FULLY-SPECIFIED",
             ":DEGREES" if angle_unit == "deg" else ":RADIANS"]
    return "\n".join(lines) + "\n"


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
