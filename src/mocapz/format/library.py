"""The ``.mczdb`` library framing: magic, JSON index, named sections, shared skeletons, per-clip checksums.

A library holds many clips coded by one codec with data shared between clips (a skeleton stored once for
the clips that have it; the pattern codec's body-part databases; the PGA codec's pose model). This module
knows nothing of what the codecs' sections hold: clips are put in *groups*; each group has its shared
sections, each clip its layout header and own sections, and one clip's sections are read back without the
other clips' (:func:`read_members` reads only them from a file).

Byte layout::

    offset  size  field
    0       5     magic b"MCZL\\x1a"
    5       1     library format version (2; version 1 is read too)
    6       var   uvarint n, then n bytes: zstd-compressed JSON index (codec, skeletons, groups, clips)
    ...     var   uvarint section count, then per section: 1 byte name length k, k bytes ASCII name,
                  uvarint length m, m bytes payload
    end-4   4     CRC-32 (zlib, little endian) of every byte before it

Sections: ``s<k>`` skeleton ``k`` (version 2; :func:`mocapz.format.layout.encode_skeleton`); ``g<i>.<key>``
the shared sections of group ``i``; ``c<j>.L`` layout header of clip ``j`` (version 1: a complete ``.mcz``
layout; version 2: the layout without the skeleton, :func:`mocapz.format.layout.encode_member_layout`, when
the clip's index entry names a ``skeleton``); ``c<j>.<key>`` the clip's own sections. The keys of the
codecs' library modes are in ``docs/format.md`` section 7.

The index holds ``codec``, ``codec_version``, ``groups`` (one object per group, written by the codec's
caller; version 2 adds ``crc``), ``clips`` (per clip: ``name``, ``group``, ``frames``, ``frame_rate``,
``kind``, ``format``, ``raw_bytes``; version 2 adds ``skeleton`` (or null) and ``crc``), ``settings`` and
(version 2) ``skeletons`` (per skeleton its ``crc``). A ``crc`` is the CRC-32 of the sections of that clip,
group or skeleton, each as stored (name length, name, length, payload), in file order: a damaged clip is
found without the others (:meth:`Library.damaged`).
"""

from __future__ import annotations

import json
import os
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import zstandard

from mocapz.errors import FormatError, MocapzError
from mocapz.format.container import read_sections, seal, write_sections
from mocapz.format.entropy import read_uvarint, safe_zstd_decompress, write_uvarint
from mocapz.format.layout import decode_member_header, encode_member_layout, encode_skeleton
from mocapz.format.library_index import check_index
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, Motion

MAGIC = b"MCZL\x1a"
FORMAT_VERSION = 2
READ_VERSIONS = (1, 2)
LAYOUT_KEY = "L"


class Sections(dict[str, bytes]):
    """Named sections of one group or clip, keyed without their ``g<i>.`` / ``c<j>.`` prefix.

    Reading a missing key raises :class:`~mocapz.errors.FormatError` naming the full section.
    """

    def __init__(self, prefix: str, items: dict[str, bytes]) -> None:
        super().__init__(items)
        self.prefix = prefix

    def __missing__(self, key: str) -> bytes:
        raise _missing(self.prefix + key)


def _missing(name: str) -> FormatError:
    return FormatError(None, f"corrupted library (missing section {name!r})")


def _span_crc(sections: dict[str, bytes], prefix: str) -> int:
    """CRC-32 of the sections whose names start with ``prefix``, as stored, in order."""
    crc = 0
    for key, payload in sections.items():
        if key.startswith(prefix):
            k = key.encode("ascii")
            crc = zlib.crc32(bytes([len(k)]) + k + write_uvarint(len(payload)) + payload, crc)
    return crc & 0xFFFFFFFF


def _skeleton_crc(sections: dict[str, bytes], k: int) -> int | None:
    """CRC-32 of skeleton ``k``'s section ``s<k>`` alone (not ``s<k>0``... : a name prefix would take them in),
    or None when it is missing."""
    key = f"s{k}"
    return _span_crc({key: sections[key]}, key) if key in sections else None


@dataclass
class Library:
    """A parsed library: its JSON index and its raw (undecoded) sections, in file order."""

    index: dict[str, Any] = field(default_factory=dict)
    sections: dict[str, bytes] = field(default_factory=dict)
    version: int = FORMAT_VERSION
    _skeletons: dict[bytes, int] = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------ writing
    def add_group(self, group: int, sections: dict[str, bytes]) -> None:
        """Append the shared sections of group ``group``."""
        for key, payload in sections.items():
            self.sections[f"g{group}.{key}"] = payload

    def skeleton_of(self, motion: AnyMotion) -> int | None:
        """The number of ``motion``'s skeleton in this library, stored now if it is new (None for markers)."""
        if not isinstance(motion, Motion):
            return None
        if not self._skeletons:  # a library read back: its skeletons, by their bytes
            for k in range(len(self.index.get("skeletons", []))):
                self._skeletons[self.sections[f"s{k}"]] = k
        key = encode_skeleton(motion.skeleton)  # equal bytes: the same skeleton, exactly (round trips are exact)
        if key not in self._skeletons:
            k = len(self.index.setdefault("skeletons", []))
            self.sections[f"s{k}"] = key
            self.index["skeletons"].append({})
            self._skeletons[key] = k
        return self._skeletons[key]

    def add_clip(self, clip: int, motion: AnyMotion, sections: dict[str, bytes]) -> int | None:
        """Append clip ``clip``'s layout header (from ``motion``, its skeleton stored once in the library) and
        its own sections; returns the clip's skeleton number (None for markers)."""
        sk = self.skeleton_of(motion)
        self.sections[f"c{clip}.{LAYOUT_KEY}"] = encode_member_layout(motion)
        for key, payload in sections.items():
            self.sections[f"c{clip}.{key}"] = payload
        return sk

    def seal_index(self) -> None:
        """Fill in the checksums of every skeleton, group and clip (done by :meth:`to_bytes`)."""
        for k, entry in enumerate(self.index.get("skeletons", [])):
            entry["crc"] = _skeleton_crc(self.sections, k)
        for name, prefix in (("groups", "g"), ("clips", "c")):
            for i, entry in enumerate(self.index[name]):
                entry["crc"] = _span_crc(self.sections, f"{prefix}{i}.")

    def to_bytes(self) -> bytes:
        if self.version != FORMAT_VERSION:
            raise MocapzError(f"library format version {self.version} is read, not written (write version "
                              f"{FORMAT_VERSION}: compress the clips again)")
        self.seal_index()
        text = json.dumps(self.index, separators=(",", ":")).encode()
        head = zstandard.ZstdCompressor(level=19).compress(text)
        out = bytearray(MAGIC + bytes([FORMAT_VERSION]) + write_uvarint(len(head)) + head)
        out += write_sections(self.sections)
        return seal(out)

    # ------------------------------------------------------------------ reading
    @classmethod
    def from_bytes(cls, data: bytes, path: str | os.PathLike[str] | None = None, check: bool = True) -> Library:
        """Parse library bytes; ``check=False`` skips the whole-file checksum (:meth:`damaged` then says
        which clips are damaged)."""
        try:
            return cls._parse(data, check)
        except FormatError as exc:
            raise FormatError(path, exc.problem) from None

    @classmethod
    def _parse(cls, data: bytes, check: bool) -> Library:
        version, index, pos = _head(data)
        (crc,) = struct.unpack("<I", data[-4:])
        if check and zlib.crc32(data[:-4]) & 0xFFFFFFFF != crc:
            raise FormatError(None, "corrupted or truncated library (checksum mismatch)")
        body = memoryview(data)[:-4]
        sections, pos = read_sections(body, pos, "library")
        if pos != len(body):
            raise FormatError(None, "corrupted library (length mismatch)")
        return cls(index, sections, version)

    def clip_names(self) -> list[str]:
        return [c["name"] for c in self.index["clips"]]

    def clip_number(self, name: str, path: str | os.PathLike[str] | None = None) -> int:
        """Index of the clip called ``name``; raises MocapzError listing the clips if there is none."""
        names = self.clip_names()
        if name not in names:
            shown = ", ".join(names[:20]) + (f", ... ({len(names)} in all)" if len(names) > 20 else "")
            raise MocapzError(f"{path or '<library>'}: no clip named {name!r} (clips: {shown})")
        return names.index(name)

    def group_of(self, clip: int) -> int:
        return int(self.index["clips"][clip]["group"])

    def group_sections(self, group: int) -> Sections:
        """The shared sections of group ``group``, keyed without their ``g<i>.`` prefix."""
        prefix = f"g{group}."
        return Sections(prefix, {k[len(prefix) :]: v for k, v in self.sections.items() if k.startswith(prefix)})

    def clip_header(self, clip: int) -> ClipHeader:
        """The typed layout header of clip ``clip`` (joined with its skeleton)."""
        key = f"c{clip}.{LAYOUT_KEY}"
        if key not in self.sections:
            raise _missing(key)
        sk = self.index["clips"][clip].get("skeleton")
        if sk is None:
            return decode_member_header(self.sections[key], None)
        if not isinstance(sk, int) or f"s{sk}" not in self.sections:
            raise _missing(f"s{sk}")
        return decode_member_header(self.sections[key], self.sections[f"s{sk}"])

    def clip_sections(self, clip: int) -> dict[str, bytes]:
        """Clip ``clip``'s own sections (its layout header left out), keyed without their ``c<j>.`` prefix."""
        prefix = f"c{clip}."
        layout = prefix + LAYOUT_KEY
        return {k[len(prefix) :]: v for k, v in self.sections.items() if k.startswith(prefix) and k != layout}

    def clip_bytes(self, clip: int) -> int:
        """Bytes of the clip's own sections (layout header included), as stored."""
        return sum(len(k) + 2 + len(v) for k, v in self.sections.items() if k.startswith(f"c{clip}."))

    def damaged(self, clip: int) -> list[str]:
        """What of clip ``clip`` fails its checksum: ``"clip"``, ``"group"``, ``"skeleton"`` (empty: intact;
        a version 1 library has no per-clip checksums, only the whole file's)."""
        if self.version < 2:
            return []
        entry = self.index["clips"][clip]
        out = []
        if entry.get("crc") != _span_crc(self.sections, f"c{clip}."):
            out.append("clip")
        g = self.group_of(clip)
        if self.index["groups"][g].get("crc") != _span_crc(self.sections, f"g{g}."):
            out.append("group")
        sk = entry.get("skeleton")
        if sk is not None and self.index["skeletons"][sk].get("crc") != _skeleton_crc(self.sections, sk):
            out.append("skeleton")
        return out

    def summary(self, group_totals: tuple[str, ...] = ()) -> dict[str, Any]:
        """Clips (names, frames), groups, shared bytes and raw bytes; ``group_totals`` names numeric fields
        of the group entries to sum."""
        clips = self.index["clips"]
        out: dict[str, Any] = {
            "codec": self.index.get("codec"), "codec_version": self.index.get("codec_version"),
            "format_version": self.version, "clip_count": len(clips), "clips": [c["name"] for c in clips],
            "frames": [int(c["frames"]) for c in clips], "groups": len(self.index["groups"]),
            "skeletons": len(self.index.get("skeletons", [])),
            "shared_database_bytes": sum(len(v) for k, v in self.sections.items() if k.startswith("g")),
            "shared_skeleton_bytes": sum(len(v) for k, v in self.sections.items() if k.startswith("s")),
        }
        for name in group_totals:
            out[name] = sum(int(g.get(name, 0)) for g in self.index["groups"])
        out["raw_bytes"] = sum(int(c["raw_bytes"]) for c in clips)
        return out


def _head(data: bytes | memoryview) -> tuple[int, dict[str, Any], int]:
    """Version, index and the position after it, of library bytes (at least the head of a file)."""
    if len(data) < len(MAGIC) or bytes(data[: len(MAGIC)]) != MAGIC:
        raise FormatError(None, "not a mocapz library (.mczdb): bad magic bytes")
    if len(data) < len(MAGIC) + 6:
        raise FormatError(None, "truncated library")
    version = data[len(MAGIC)]
    if version not in READ_VERSIONS:
        raise FormatError(None, f"unsupported library format version {version} (this mocapz reads "
                                f"{', '.join(map(str, READ_VERSIONS))})")
    n, pos = read_uvarint(data, len(MAGIC) + 1)
    if pos + n > len(data):
        raise FormatError(None, "truncated library index")
    try:
        index = json.loads(safe_zstd_decompress(bytes(data[pos : pos + n]), 1 << 26, "library index"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise FormatError(None, f"corrupted library index ({exc})") from None
    check_index(index, version)
    return version, index, pos + n


def read_members(path: str | os.PathLike[str], wanted: list[str]) -> Library:
    """The library at ``path`` with only the named clips' sections loaded (and their groups' and skeletons'),
    each checked against its checksum; the other clips' payloads are skipped, not read.

    A version 1 library has no per-clip checksums: it is read whole and its file checksum checked.
    """
    p = Path(path)
    if not p.is_file():
        raise FormatError(p, "no such file")
    try:
        with p.open("rb") as f:
            lib = _read_selected(f, wanted, p)
    except FormatError as exc:
        raise FormatError(p, exc.problem) from None
    return lib


def _read_selected(f: BinaryIO, wanted: list[str], path: Path) -> Library:
    head = f.read(1 << 16)
    version, index, pos = _head(head)
    if pos > len(head) - 16:
        head += f.read(pos + 16 - len(head))
        version, index, pos = _head(head)
    if version < 2:
        f.seek(0)
        return Library.from_bytes(f.read())
    lib = Library(index, {}, version)
    clips = [lib.clip_number(name, path) for name in wanted]
    keep = tuple(f"c{j}." for j in clips) + tuple(f"g{lib.group_of(j)}." for j in clips)
    skels = {f"s{index['clips'][j].get('skeleton')}" for j in clips}
    size = f.seek(0, os.SEEK_END)
    f.seek(pos)
    count = _uvarint(f)
    for _ in range(count):
        k = f.read(1)
        if not k:
            raise FormatError(None, "truncated library sections")
        key = f.read(k[0]).decode("ascii", errors="replace")
        m = _uvarint(f)
        if f.tell() + m > size - 4:
            raise FormatError(None, f"truncated library section {key!r}")
        if key.startswith(keep) or key in skels:
            lib.sections[key] = f.read(m)
        else:
            f.seek(m, os.SEEK_CUR)
    for j in clips:
        bad = lib.damaged(j)
        if bad:
            raise FormatError(None, f"clip {index['clips'][j]['name']!r} is damaged (checksum mismatch of its "
                                    f"{' and '.join(bad)} sections)")
    return lib


def _uvarint(f: BinaryIO) -> int:
    out, shift = 0, 0
    while True:
        b = f.read(1)
        if not b:
            raise FormatError(None, "truncated library")
        out |= (b[0] & 0x7F) << shift
        if b[0] < 0x80 or shift > 63:
            return out
        shift += 7


def clip_entry(motion: AnyMotion, name: str, group: int, skeleton: int | None = None) -> dict[str, Any]:
    """The index entry of a clip."""
    return {"name": name, "group": group, "skeleton": skeleton, "frames": motion.n_frames,
            "frame_rate": motion.frame_rate, "kind": motion.kind, "format": motion.source_format,
            "raw_bytes": motion.raw_bytes}


def unique_names(motions: list[AnyMotion], taken: list[str] | None = None) -> list[str]:
    """Clip names, repeated ones numbered (``walk``, ``walk_2``...); ``taken``: names already in the library."""
    seen: dict[str, int] = {}
    used = set(taken or [])
    out = []
    for m in motions:
        base = m.name or "clip"
        seen[base] = seen.get(base, 0) + 1
        name = base if seen[base] == 1 else f"{base}_{seen[base]}"
        while name in used:
            seen[base] += 1
            name = f"{base}_{seen[base]}"
        used.add(name)
        out.append(name)
    return out


def read_library(path: str | os.PathLike[str]) -> tuple[Library, bytes]:
    """Read and parse a ``.mczdb`` file: the library and the file's bytes."""
    p = Path(path)
    if not p.is_file():
        raise FormatError(p, "no such file")
    data = p.read_bytes()
    return Library.from_bytes(data, p), data
