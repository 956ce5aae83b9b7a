"""Compact serialisation of a motion's layout (skeleton or marker set, rate, names) for the container.

The layout is JSON compressed with zstd and a built-in dictionary of common joint and marker names, so
that a 31-joint CMU skeleton costs a few hundred bytes and short clips are not swamped by headers.
Offsets are stored as decimal text at their own precision, so they come back bit-exactly.
"""

from __future__ import annotations

import functools
import json
from typing import Any

import numpy as np
import zstandard

from mocapz.errors import FormatError
from mocapz.format.entropy import read_uvarint, unzigzag, write_uvarint, zigzag
from mocapz.format.layout_check import check_layout, check_offset_names
from mocapz.format.planes import decompressor, read_uvarints
from mocapz.io.common import detect_decimals
from mocapz.model.header import KEPT_METADATA, ClipHeader
from mocapz.model.motion import AnyMotion, Motion
from mocapz.model.skeleton import Skeleton

_DICT_TEXT = (
    '{"kind":"skeleton","names":["Hips","LHipJoint","LeftUpLeg","LeftLeg","LeftFoot","LeftToeBase",'
    '"RHipJoint","RightUpLeg","RightLeg","RightFoot","RightToeBase","LowerBack","Spine","Spine1","Neck",'
    '"Neck1","Head","LeftShoulder","LeftArm","LeftForeArm","LeftHand","LeftFingerBase","LeftHandIndex1",'
    '"LThumb","RightShoulder","RightArm","RightForeArm","RightHand","RightFingerBase","RightHandIndex1",'
    '"RThumb"],"parents":[-1,0,1,2,3,4,0,6,7,8,9,0,11,12,13,14,15,13,17,18,19,20,21,20,13,24,25,26,27,'
    '28,27],"channels":["XposYposZposZrotYrotXrot","ZrotYrotXrot","XrotYrotZrot","ZrotXrotYrot"],'
    '"root","lhipjoint","lfemur","ltibia","lfoot","ltoes","rhipjoint","rfemur","rtibia","rfoot","rtoes",'
    '"lowerback","upperback","thorax","lowerneck","upperneck","head","lclavicle","lhumerus","lradius",'
    '"lwrist","lhand","lfingers","lthumb","rclavicle","rhumerus","rradius","rwrist","rhand","rfingers",'
    '"rthumb","Chest","Chest2","Collar","UpArm","LowArm","UpLeg","LowLeg","Toe","_End",'
    '"LFHD","RFHD","LBHD","RBHD","C7","T10","CLAV","STRN","RBAC","LSHO","LUPA","LELB","LFRM","LWRA","LWRB",'
    '"LFIN","RSHO","RUPA","RELB","RFRM","RWRA","RWRB","RFIN","LFWT","RFWT","LBWT","RBWT","LTHI","LKNE",'
    '"LSHN","LANK","LHEE","LTOE","LMT5","RTHI","RKNE","RSHN","RANK","RHEE","RTOE","RMT5",'
    '"offsets":[[0,0,0],"end_sites":[[5,[0,-0,1.09718],"angle_unit":"deg","unit_cm":5.644444444444445,'
    '"unit_note":"CMU skeleton: 1 unit = 2.54/0.45 cm","frame_rate":120.0,"source_format":"bvh",'
    '"decimals":[4,4,4,4,4,4,0,0,0,"kind":"markers","labels":[,"units":"mm","metadata":{"frame_time":'
    '0.0083333,"file_bytes":'
)
_DICT = zstandard.ZstdCompressionDict(_DICT_TEXT.encode(), dict_type=zstandard.DICT_TYPE_RAWCONTENT)

_SHORT = {"Xposition": "Xpos", "Yposition": "Ypos", "Zposition": "Zpos",
          "Xrotation": "Xrot", "Yrotation": "Yrot", "Zrotation": "Zrot"}
_LONG = {v: k for k, v in _SHORT.items()}



def _num(v: float) -> float | int:
    f = float(v)
    return int(f) if f.is_integer() and abs(f) < 2**53 and not (f == 0 and np.signbit(f)) else f


def skeleton_to_dict(sk: Skeleton) -> dict[str, Any]:
    d: dict[str, Any] = {
        "names": sk.names,
        "parents": sk.parents.tolist(),
        "channels": ["".join(_SHORT[c] for c in chs) for chs in sk.channels],
        "orders": sk.rotation_order,
        "offsets": [[_num(v) for v in row] for row in sk.offsets],
        "end_sites": [[int(j), [_num(v) for v in off], n] for j, off, n in sk.end_sites],
        "angle_unit": sk.angle_unit,
        "unit_cm": sk.unit_cm,
        "unit_note": sk.unit_note,
    }
    if not sk.has_identity_axes():
        assert sk.axis is not None
        d["axis"] = sk.axis.reshape(-1).tolist()
    if sk.extra:
        d["extra"] = sk.extra
    return d


@functools.lru_cache(maxsize=1024)
def _channel_names(codes: str) -> tuple[str, ...]:
    """The channel names of a joint's channel codes (``"XposYposZpos"``; checked by ``check_layout``)."""
    return tuple(_LONG[codes[i : i + 4]] for i in range(0, len(codes), 4))


def skeleton_from_dict(d: dict[str, Any]) -> Skeleton:
    chs = [_channel_names(s) for s in d["channels"]]
    n = len(d["names"])
    axis = np.asarray(d["axis"], dtype=np.float64).reshape(n, 3, 3) if "axis" in d else None
    return Skeleton(
        names=list(d["names"]),
        parents=np.asarray(d["parents"], dtype=np.int64),
        offsets=np.asarray(d["offsets"], dtype=np.float64).reshape(n, 3),
        channels=chs,
        rotation_order=list(d["orders"]),
        axis=axis,
        end_sites=[(int(j), np.asarray(off, dtype=np.float64), str(name)) for j, off, name in d["end_sites"]],
        angle_unit=d["angle_unit"],
        unit_cm=d["unit_cm"],
        unit_note=d["unit_note"],
        extra=d.get("extra", {}),
    )


def layout_dict(motion: AnyMotion) -> dict[str, Any]:
    """Everything about a motion except its sample values."""
    meta = {k: motion.metadata[k] for k in KEPT_METADATA if k in motion.metadata}
    if isinstance(motion, Motion):
        return {
            "kind": "skeleton",
            **skeleton_to_dict(motion.skeleton),
            "frames": motion.n_frames,
            "frame_rate": motion.frame_rate,
            "name": motion.name,
            "source_format": motion.source_format,
            "decimals": None if motion.decimals is None else motion.decimals.tolist(),
            "metadata": meta,
        }
    d: dict[str, Any] = {
        "kind": "markers",
        "labels": motion.labels,
        "units": motion.units,
        "frames": motion.n_frames,
        "frame_rate": motion.frame_rate,
        "name": motion.name,
        "source_format": motion.source_format,
        "decimals": motion.decimals,
        "metadata": meta,
    }
    if motion.quantum is not None:  # absent when None: older layouts keep their bytes
        d["quantum"] = float(motion.quantum)
    return d


def encode_layout(motion: AnyMotion) -> bytes:
    """Layout bytes: ``uvarint n``, ``n`` bytes of zstd JSON (raw-content dictionary), then a numeric block.

    For skeletons whose offsets have a finite decimal count ``q`` (BVH text, ASF), the joint and end-site
    offsets leave the JSON (``"offsets": null``, ``"num_dec": q``) and follow as zig-zag varints of
    ``round(value * 10**q)``, joints then end sites, x y z each: a zero costs one byte.
    """
    return _pack(layout_dict(motion), motion.skeleton if isinstance(motion, Motion) else None)


#: the layout fields a skeleton holds (those a library stores once per skeleton, :func:`encode_skeleton`)
SKELETON_FIELDS = ("names", "parents", "channels", "orders", "offsets", "end_sites", "angle_unit", "unit_cm",
                   "unit_note", "axis", "extra")
SHARED = "shared"  # the ``"skeleton"`` field of a member layout whose skeleton is stored apart


def encode_skeleton(sk: Skeleton) -> bytes:
    """A skeleton alone, packed like a layout (``"kind": "skeleton"`` and the :data:`SKELETON_FIELDS`):
    a library stores it once for the clips that share it (:func:`encode_member_layout`)."""
    return _pack({"kind": "skeleton", **skeleton_to_dict(sk)}, sk)


def encode_member_layout(motion: AnyMotion) -> bytes:
    """The layout of a library clip whose skeleton is stored apart (:func:`encode_skeleton`): every field but
    the skeleton's, and ``"skeleton": "shared"``. A marker clip's layout is :func:`encode_layout`'s."""
    if not isinstance(motion, Motion):
        return encode_layout(motion)
    d = {k: v for k, v in layout_dict(motion).items() if k not in SKELETON_FIELDS}
    d["skeleton"] = SHARED
    return _pack(d, None)


def decode_member_header(data: bytes, skeleton: bytes | None) -> ClipHeader:
    """The header of a library clip: its layout (:func:`encode_member_layout`) joined with the skeleton it
    refers to (:func:`encode_skeleton`); a complete layout (``skeleton`` None) as :func:`decode_header`."""
    if skeleton is None:
        return decode_header(data)
    d = _unpack(data)
    if d.get("kind") != "skeleton" or d.pop("skeleton", None) != SHARED or any(k in d for k in SKELETON_FIELDS):
        raise FormatError(None, "corrupted layout header (not a library clip's layout)")
    sk = _skeleton_dict(skeleton)
    if d.pop("_block"):
        raise FormatError(None, "corrupted layout header (trailing bytes)")
    merged = {**d, **sk}
    check_layout(merged)
    return header_from_layout(merged)


def _skeleton_dict(data: bytes) -> dict[str, Any]:
    sk = _unpack(data)
    if sk.pop("kind", None) != "skeleton" or "num_dec" not in sk and "offsets" not in sk:
        raise FormatError(None, "corrupted skeleton layout")
    if "num_dec" in sk:
        _unpack_offsets(sk, sk.pop("_block"))
    elif sk.pop("_block"):
        raise FormatError(None, "corrupted skeleton layout (trailing bytes)")
    return sk


def decode_skeleton(data: bytes) -> Skeleton:
    """Inverse of :func:`encode_skeleton` (checked as a layout of no frames)."""
    d = {"kind": "skeleton", "frames": 0, "frame_rate": 1.0, "name": "", "source_format": "bvh",
         **_skeleton_dict(data)}
    check_layout(d)
    try:
        return skeleton_from_dict(d)
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise FormatError(None, f"corrupted skeleton layout ({exc})") from None


def _pack(d: dict[str, Any], sk: Skeleton | None) -> bytes:
    """``d`` as zstd JSON, the skeleton's offsets (when given and decimal) as a numeric block after it."""
    block = b""
    if sk is not None:
        nums = np.concatenate([sk.offsets.ravel()] + [np.asarray(o, dtype=np.float64) for _, o, _ in sk.end_sites])
        dec = detect_decimals(nums[:, None]) if nums.size else np.zeros(1, dtype=np.int64)
        if dec is not None and int(dec[0]) <= 9:
            q = int(dec[0])
            ints = np.round(nums * 10.0**q).astype(np.int64)
            d["offsets"] = None
            d["end_sites"] = [[j, n] for j, _, n in d["end_sites"]]
            d["num_dec"] = q
            block = b"".join(write_uvarint(int(z)) for z in zigzag(ints))
    text = json.dumps(d, separators=(",", ":"), sort_keys=False).encode()
    z = zstandard.ZstdCompressor(level=19, dict_data=_DICT, write_checksum=False,
                                 write_content_size=True, write_dict_id=False).compress(text)
    return write_uvarint(len(z)) + z + block


def _unpack(data: bytes) -> dict[str, Any]:
    """The JSON object of packed layout bytes, with its numeric block as ``"_block"`` (unchecked)."""
    n, pos = read_uvarint(data, 0)
    z, block = data[pos : pos + n], data[pos + n :]
    if len(z) != n:
        raise FormatError(None, "truncated layout header")
    try:
        size = zstandard.get_frame_parameters(z).content_size
        if size == zstandard.CONTENTSIZE_UNKNOWN or size > 1 << 26:
            raise FormatError(None, "corrupted layout header (implausible size)")
        d = json.loads(decompressor(_DICT).decompress(z, max_output_size=1 << 26))
    except (zstandard.ZstdError, ValueError, UnicodeDecodeError) as exc:
        raise FormatError(None, f"corrupted layout header ({exc})") from None
    if not isinstance(d, dict):
        raise FormatError(None, "corrupted layout header (not an object)")
    d["_block"] = bytes(block)
    return d


def decode_layout(data: bytes) -> dict[str, Any]:
    d = _unpack(data)
    block = d.pop("_block")
    if d.get("kind") not in ("skeleton", "markers"):
        raise FormatError(None, "corrupted layout header (unknown kind)")
    if d["kind"] == "skeleton" and "num_dec" in d:
        _unpack_offsets(d, block)
    elif block:
        raise FormatError(None, "corrupted layout header (trailing bytes)")
    check_layout(d)
    return d


def _unpack_offsets(d: dict[str, Any], block: bytes) -> None:
    count = check_offset_names(d)
    q = d.pop("num_dec")
    vals, pos = read_uvarints(block, 0, 3 * count)
    if pos != len(block):
        raise FormatError(None, "corrupted layout header (offset block)")
    joints, ends = len(d["names"]), d["end_sites"]
    nums = unzigzag(vals) / 10.0**q
    d["offsets"] = nums[: 3 * joints].reshape(joints, 3).tolist()
    d["end_sites"] = [[j, nums[3 * joints + 3 * i : 3 * joints + 3 * i + 3].tolist(), name]
                      for i, (j, name) in enumerate(ends)]


def decode_header(data: bytes) -> ClipHeader:
    """The typed header codecs get (:class:`~mocapz.model.header.ClipHeader`) from layout bytes."""
    return header_from_layout(decode_layout(data))


def header_from_layout(layout: dict[str, Any]) -> ClipHeader:
    """A :class:`~mocapz.model.header.ClipHeader` from a decoded layout dict (checked by ``decode_layout``)."""
    try:
        common = dict(frames=int(layout["frames"]), frame_rate=float(layout["frame_rate"]), name=str(layout["name"]),
                      source_format=str(layout["source_format"]), metadata=dict(layout.get("metadata", {})))
        if layout["kind"] == "skeleton":
            dec = layout.get("decimals")
            return ClipHeader("skeleton", skeleton=skeleton_from_dict(layout),
                              decimals=None if dec is None else np.asarray(dec, dtype=np.int64), **common)
        labels = [str(x) for x in layout["labels"]]
        quantum = layout.get("quantum")
        return ClipHeader("markers", labels=labels, units=str(layout["units"]), decimals=layout.get("decimals"),
                          quantum=None if quantum is None else float(quantum), **common)
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise FormatError(None, f"corrupted layout header ({exc})") from None
