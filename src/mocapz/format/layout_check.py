"""Checks of a decoded layout dict (:mod:`mocapz.format.layout`) before it becomes a ClipHeader.

The layout is read from a file, so it may hold anything JSON can say. Every field is checked for its type,
its size and its range here, once, so that decoders get a consistent header: a skeleton whose lists all
have one entry per joint, whose channel names are known, whose rotation orders name exactly the axes of
the joint's rotation channels, whose offsets, end sites and axes are finite 3-vectors and rotations, and
whose decimals cover every channel; frame counts and rates that are numbers in range. A failed check is a
:class:`~mocapz.errors.FormatError` naming the field.
"""

from __future__ import annotations

import functools
import itertools
import math
from typing import Any

import numpy as np

from mocapz.errors import FormatError

MAX_FRAMES = 1 << 28
MAX_VALUES = 1 << 33  # frames x joints (or markers) x 6: the most a decoder may be asked to produce
MAX_DECIMALS = 15
CHANNEL_CODES = ("Xpos", "Ypos", "Zpos", "Xrot", "Yrot", "Zrot")


def _bad(field: str, problem: str) -> FormatError:
    return FormatError(None, f"corrupted layout header ({field}: {problem})")


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_real(v: Any) -> bool:
    """A finite number (an int that fits a float; JSON reads 1e999 as infinity)."""
    return _is_int(v) and abs(v) < 1 << 1000 or isinstance(v, float) and math.isfinite(v)


def _reals(values: list[Any]) -> bool:
    """Every item a finite number (:func:`_is_real`), checked at once."""
    kinds = set(map(type, values))
    if not kinds <= {int, float}:
        return False  # bool, str, None, list...: not a number
    if int in kinds and not all(abs(x) < 1 << 1000 for x in values if type(x) is int):
        return False
    return all(map(math.isfinite, values))


def _int_list(d: dict[str, Any], field: str, size: int | None = None, low: int = -(1 << 62),
             high: int = 1 << 62) -> list[int]:
    """``d[field]``: a list of ints in ``[low, high]`` (of ``size`` items when given)."""
    v = d.get(field)
    if not isinstance(v, list) or not set(map(type, v)) <= {int} or (v and not low <= min(v) <= max(v) <= high):
        raise _bad(field, f"a list of integers in {low}..{high} expected")
    if size is not None and len(v) != size:
        raise _bad(field, f"{len(v)} items where {size} are expected")
    return v


def _str_list(d: dict[str, Any], field: str, size: int | None = None) -> list[str]:
    v = d.get(field)
    if not isinstance(v, list) or not set(map(type, v)) <= {str}:
        raise _bad(field, "a list of strings expected")
    if size is not None and len(v) != size:
        raise _bad(field, f"{len(v)} items where {size} are expected")
    return v


def _vectors(vs: list[Any], field: str) -> None:
    """Every item of ``vs`` a list of three finite numbers."""
    if not all(type(v) is list and len(v) == 3 for v in vs) or not _reals(list(itertools.chain.from_iterable(vs))):
        raise _bad(field, "three finite numbers expected")


def _of_type(d: dict[str, Any], field: str, kind: type, optional: bool = False) -> None:
    """``d[field]`` is a ``kind`` (``str``, ``dict``), or absent when ``optional``."""
    if not (optional and field not in d) and not isinstance(d.get(field), kind):
        raise _bad(field, f"{kind.__name__} expected")


def check_offset_names(d: dict[str, Any]) -> int:
    """The fields the numeric offset block is read against (``names``, ``end_sites`` as ``[joint, name]``,
    ``num_dec``); returns the number of 3-vectors in the block."""
    names = _str_list(d, "names")
    ends = d.get("end_sites")
    if not isinstance(ends, list) or not all(isinstance(e, list) and len(e) == 2 and _is_int(e[0])
                                             and isinstance(e[1], str) for e in ends):
        raise _bad("end_sites", "a list of [joint, name] expected")
    if not _is_int(d.get("num_dec")) or not 0 <= d["num_dec"] <= 9:
        raise _bad("num_dec", "an integer in 0..9 expected")
    return len(names) + len(ends)


def check_layout(d: dict[str, Any]) -> None:
    """Raise FormatError unless ``d`` is a layout every decoder can rely on (see the module docstring)."""
    for field in ("name", "source_format"):
        _of_type(d, field, str)
    _of_type(d, "metadata", dict, optional=True)
    frames, rate = d.get("frames"), d.get("frame_rate")
    if not _is_int(frames) or not 0 <= frames <= MAX_FRAMES:
        raise _bad("frames", f"implausible frame count {frames!r}")
    if not _is_real(rate) or not rate > 0:
        raise _bad("frame_rate", f"frame rate {rate!r}")
    if d["kind"] == "markers":
        width = len(_str_list(d, "labels"))
        _of_type(d, "units", str)
        dec = d.get("decimals")
        if dec is not None and not (_is_int(dec) and 0 <= dec <= MAX_DECIMALS):
            raise _bad("decimals", f"an integer in 0..{MAX_DECIMALS} or null expected")
        quantum = d.get("quantum")
        if quantum is not None and not (_is_real(quantum) and quantum > 0):
            raise _bad("quantum", "a positive number or null expected")
    else:
        width = _check_skeleton(d)
    if frames * max(width, 1) * 6 > MAX_VALUES:
        raise _bad("frames", f"implausible frame count {frames} for {width} joints or markers")


def _check_skeleton(d: dict[str, Any]) -> int:
    n = len(_str_list(d, "names"))
    if n == 0:
        raise _bad("names", "a skeleton without joints")
    parents = _int_list(d, "parents", n, -1, n)
    if any(p >= j for j, p in enumerate(parents)):
        raise _bad("parents", "a parent must come before its child")
    channels = _str_list(d, "channels", n)
    orders = _str_list(d, "orders", n)
    n_channels = 0
    for j, (chs, order) in enumerate(zip(channels, orders, strict=True)):
        n_channels += _joint_channels(j, chs, order)
    offsets = d.get("offsets")
    if not isinstance(offsets, list) or len(offsets) != n:
        raise _bad("offsets", f"one offset per joint ({n}) expected")
    _vectors(offsets, "offsets")
    ends = d.get("end_sites")
    if not isinstance(ends, list) or not all(isinstance(e, list) and len(e) == 3 for e in ends):
        raise _bad("end_sites", "a list of [joint, offset, name] expected")
    for j, _, name in ends:
        if not _is_int(j) or not 0 <= j < n or not isinstance(name, str):
            raise _bad("end_sites", "end site on an unknown joint")
    _vectors([e[1] for e in ends], "end_sites")
    if "axis" in d:
        axis = d["axis"]
        if not isinstance(axis, list) or len(axis) != 9 * n or not _reals(axis):
            raise _bad("axis", f"{9 * n} finite numbers expected")
        a = np.asarray(axis, dtype=np.float64).reshape(n, 3, 3)
        if not np.allclose(a @ np.swapaxes(a, 1, 2), np.eye(3), atol=1e-6) or not np.all(np.linalg.det(a) > 0):
            raise _bad("axis", "rotation matrices expected")
    if d.get("angle_unit") not in ("deg", "rad"):
        raise _bad("angle_unit", "'deg' or 'rad' expected")
    unit = d.get("unit_cm")
    if unit is not None and not (_is_real(unit) and unit > 0):
        raise _bad("unit_cm", "a positive number or null expected")
    _of_type(d, "unit_note", str)
    _of_type(d, "extra", dict, optional=True)
    if d.get("decimals") is not None:
        _int_list(d, "decimals", n_channels, 0, MAX_DECIMALS)
    return n


@functools.lru_cache(maxsize=1024)
def _joint_channels(j: int, chs: str, order: str) -> int:
    """The number of channels of joint ``j`` (``chs``: its channel codes, ``order``: its rotation order);
    FormatError unless they are known, distinct and the order names exactly its rotation axes (the same few
    joint layouts recur in every file: the answers are kept)."""
    codes = [chs[i : i + 4] for i in range(0, len(chs), 4)]
    if len(chs) % 4 or any(c not in CHANNEL_CODES for c in codes) or len(set(codes)) != len(codes):
        raise _bad("channels", f"joint {j}: unknown or repeated channels {chs[:40]!r}")
    rot = sorted(c[0] for c in codes if c.endswith("rot"))
    if sorted(order) != rot or len(set(order)) != len(order):
        raise _bad("orders", f"joint {j}: rotation order {order[:8]!r} for rotation channels {''.join(rot)!r}")
    return len(codes)
