"""The checks of a library's JSON index (:mod:`mocapz.format.library`), made once when it is parsed.

The index is JSON inside a checksummed file, but a checksum only says the bytes are the ones written: a file
written by a faulty or hostile writer can hold a clip that is not an object, a group number past the groups, a
skeleton number past the skeletons, a name twice. Every field a reader uses is checked here (type and range),
so that readers can index with it and a bad index is one :class:`~mocapz.errors.FormatError` naming what is
wrong, never a ``KeyError`` or ``TypeError`` from deep inside.

Fields (``format`` and the codec's own group fields are not used by the readers, so not checked):

- ``codec`` (str), ``codec_version`` (int), ``clips`` and ``groups`` (lists), ``skeletons`` (a list; version
  2), ``settings`` (an object, when present);
- a clip: ``name`` (a non-empty string, unique), ``group`` (an int naming a group), ``frames`` (an int >= 0),
  ``frame_rate`` (a finite number > 0), ``kind`` (str), ``raw_bytes`` (an int >= 0), and in version 2
  ``skeleton`` (null or an int naming a skeleton) and ``crc`` (a 32-bit int);
- a group: an object; in version 2 its ``crc``; ``clips``, ``segments`` and ``clusters`` ints >= 0 when present;
- a skeleton: an object with its ``crc``.
"""

from __future__ import annotations

import math
from typing import Any

from mocapz.errors import FormatError


def check_index(index: Any, version: int) -> None:
    """Raise FormatError (without a path: the caller adds it) unless ``index`` is a well-formed library index of
    format ``version``."""
    if not isinstance(index, dict) or not isinstance(index.get("clips"), list) \
            or not isinstance(index.get("groups"), list):
        raise _bad("no list of clips and groups")
    if not isinstance(index.get("codec"), str) or not _count(index.get("codec_version")):
        raise _bad("its codec or codec version")
    if not isinstance(index.get("settings", {}), dict):
        raise _bad("its settings")
    skeletons = index.get("skeletons", [] if version < 2 else None)
    if not isinstance(skeletons, list):
        raise _bad("no list of skeletons")
    for k, entry in enumerate(skeletons):
        if not isinstance(entry, dict) or not _crc(entry.get("crc")):
            raise _bad(f"skeleton {k}")
    groups = index["groups"]
    for g, entry in enumerate(groups):
        if not isinstance(entry, dict) or (version >= 2 and not _crc(entry.get("crc"))) \
                or any(key in entry and not _count(entry[key]) for key in ("clips", "segments", "clusters")):
            raise _bad(f"group {g}")
    names: set[str] = set()
    for j, entry in enumerate(index["clips"]):
        problem = _clip_problem(entry, len(groups), len(skeletons), version, names)
        if problem:
            raise _bad(f"clip {j}: {problem}")
        names.add(entry["name"])


def _clip_problem(entry: Any, groups: int, skeletons: int, version: int, names: set[str]) -> str | None:
    """What is wrong with a clip's entry (None: nothing)."""
    if not isinstance(entry, dict):
        return "not an object"
    name = entry.get("name")
    if not isinstance(name, str) or not name:
        return "its name"
    if name in names:
        return f"name {name!r} given twice"
    checks = (
        ("group", _count(entry.get("group")) and entry["group"] < groups),
        ("frames", _count(entry.get("frames"))),
        ("frame rate", _real(entry.get("frame_rate")) and entry["frame_rate"] > 0),
        ("kind", isinstance(entry.get("kind"), str)),
        ("raw bytes", _count(entry.get("raw_bytes"))),
        ("skeleton", entry.get("skeleton") is None or (_count(entry["skeleton"]) and entry["skeleton"] < skeletons)),
        ("checksum", version < 2 or _crc(entry.get("crc"))),
    )
    return next((what for what, ok in checks if not ok), None)


def _count(v: Any) -> bool:
    """An int (not a bool) from 0 to 2**62."""
    return isinstance(v, int) and not isinstance(v, bool) and 0 <= v < 1 << 62


def _crc(v: Any) -> bool:
    return _count(v) and v < 1 << 32


def _real(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _bad(what: str) -> FormatError:
    return FormatError(None, f"corrupted library (bad index: {what})")
