"""The ``.mczdb`` library framing: magic, JSON index, named sections, per-clip layout headers, checksum.

A library holds many clips coded by one codec with data shared between clips (the pattern codec's body-part
databases, :mod:`mocapz.codecs.patterns.library`). This module knows nothing of what the sections hold:
clips are put in *groups*; each group has its shared sections, each clip its layout header and own
sections, and one clip's sections are read back without the other clips'.

Byte layout::

    offset  size  field
    0       5     magic b"MCZL\\x1a"
    5       1     library format version (1)
    6       var   uvarint n, then n bytes: zstd-compressed JSON index (codec, groups, clips)
    ...     var   uvarint section count, then per section: 1 byte name length k, k bytes ASCII name,
                  uvarint length m, m bytes payload
    end-4   4     CRC-32 (zlib, little endian) of every byte before it

Sections: ``g<i>.<key>`` the shared sections of group ``i``; ``c<j>.L`` layout header of clip ``j`` (as in
``.mcz``, :mod:`mocapz.format.layout`); ``c<j>.<key>`` the clip's own sections. The pattern codec's keys:
``g<i>.h`` hierarchy of group ``i``; ``g<i>.d<k>`` pattern database of its node ``k``; ``g<i>.u<k>`` that
database's usage counts (prior of the clips' index coders); ``c<j>.<key>`` the clip's own pattern streams.

The index holds ``codec``, ``codec_version``, ``groups`` (one object per group, written by the codec's
caller), ``clips`` (per clip: ``name``, ``group``, ``frames``, ``frame_rate``, ``kind``, ``format``,
``raw_bytes``) and ``settings``.
"""

from __future__ import annotations

import json
import os
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zstandard

from mocapz.errors import FormatError, MocapzError
from mocapz.format.container import read_sections, seal, write_sections
from mocapz.format.entropy import read_uvarint, safe_zstd_decompress, write_uvarint
from mocapz.format.layout import decode_header, encode_layout
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion

MAGIC = b"MCZL\x1a"
FORMAT_VERSION = 1
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


@dataclass
class Library:
    """A parsed library: its JSON index and its raw (undecoded) sections, in file order."""

    index: dict[str, Any] = field(default_factory=dict)
    sections: dict[str, bytes] = field(default_factory=dict)

    # ------------------------------------------------------------------ writing
    def add_group(self, group: int, sections: dict[str, bytes]) -> None:
        """Append the shared sections of group ``group``."""
        for key, payload in sections.items():
            self.sections[f"g{group}.{key}"] = payload

    def add_clip(self, clip: int, motion: AnyMotion, sections: dict[str, bytes]) -> None:
        """Append clip ``clip``'s layout header (from ``motion``) and its own sections."""
        self.sections[f"c{clip}.{LAYOUT_KEY}"] = encode_layout(motion)
        for key, payload in sections.items():
            self.sections[f"c{clip}.{key}"] = payload

    def to_bytes(self) -> bytes:
        text = json.dumps(self.index, separators=(",", ":")).encode()
        head = zstandard.ZstdCompressor(level=19).compress(text)
        out = bytearray(MAGIC + bytes([FORMAT_VERSION]) + write_uvarint(len(head)) + head)
        out += write_sections(self.sections)
        return seal(out)

    # ------------------------------------------------------------------ reading
    @classmethod
    def from_bytes(cls, data: bytes, path: str | os.PathLike[str] | None = None) -> Library:
        try:
            return cls._parse(data)
        except FormatError as exc:
            raise FormatError(path, exc.problem) from None

    @classmethod
    def _parse(cls, data: bytes) -> Library:
        if len(data) < len(MAGIC) or data[: len(MAGIC)] != MAGIC:
            raise FormatError(None, "not a mocapz library (.mczdb): bad magic bytes")
        if len(data) < len(MAGIC) + 6:
            raise FormatError(None, "truncated library")
        (crc,) = struct.unpack("<I", data[-4:])
        if zlib.crc32(data[:-4]) & 0xFFFFFFFF != crc:
            raise FormatError(None, "corrupted or truncated library (checksum mismatch)")
        if data[len(MAGIC)] != FORMAT_VERSION:
            raise FormatError(None, f"unsupported library format version {data[len(MAGIC)]}")
        body = memoryview(data)[:-4]
        n, pos = read_uvarint(body, len(MAGIC) + 1)
        try:
            index = json.loads(safe_zstd_decompress(bytes(body[pos : pos + n]), 1 << 26, "library index"))
        except (ValueError, UnicodeDecodeError) as exc:
            raise FormatError(None, f"corrupted library index ({exc})") from None
        pos += n
        sections, pos = read_sections(body, pos, "library")
        if pos != len(body) or not isinstance(index, dict) or "clips" not in index:
            raise FormatError(None, "corrupted library (length mismatch or bad index)")
        return cls(index, sections)

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
        """The typed layout header of clip ``clip``."""
        key = f"c{clip}.{LAYOUT_KEY}"
        if key not in self.sections:
            raise _missing(key)
        return decode_header(self.sections[key])

    def clip_sections(self, clip: int) -> dict[str, bytes]:
        """Clip ``clip``'s own sections (its layout header left out), keyed without their ``c<j>.`` prefix."""
        prefix = f"c{clip}."
        layout = prefix + LAYOUT_KEY
        return {k[len(prefix) :]: v for k, v in self.sections.items() if k.startswith(prefix) and k != layout}

    def summary(self, group_totals: tuple[str, ...] = ()) -> dict[str, Any]:
        """Clips (names, frames), groups, shared bytes and raw bytes; ``group_totals`` names numeric fields
        of the group entries to sum."""
        clips = self.index["clips"]
        out: dict[str, Any] = {
            "codec": self.index.get("codec"), "codec_version": self.index.get("codec_version"),
            "clip_count": len(clips), "clips": [c["name"] for c in clips],
            "frames": [int(c["frames"]) for c in clips], "groups": len(self.index["groups"]),
            "shared_database_bytes": sum(len(v) for k, v in self.sections.items() if k.startswith("g")),
        }
        for name in group_totals:
            out[name] = sum(int(g[name]) for g in self.index["groups"])
        out["raw_bytes"] = sum(int(c["raw_bytes"]) for c in clips)
        return out


def clip_entry(motion: AnyMotion, name: str, group: int) -> dict[str, Any]:
    """The index entry of a clip."""
    return {"name": name, "group": group, "frames": motion.n_frames, "frame_rate": motion.frame_rate,
            "kind": motion.kind, "format": motion.source_format, "raw_bytes": motion.raw_bytes}


def unique_names(motions: list[AnyMotion]) -> list[str]:
    """Clip names, repeated ones numbered (``walk``, ``walk_2``...)."""
    seen: dict[str, int] = {}
    out = []
    for m in motions:
        base = m.name or "clip"
        seen[base] = seen.get(base, 0) + 1
        out.append(base if seen[base] == 1 else f"{base}_{seen[base]}")
    return out


def read_library(path: str | os.PathLike[str]) -> tuple[Library, bytes]:
    """Read and parse a ``.mczdb`` file: the library and the file's bytes."""
    p = Path(path)
    if not p.is_file():
        raise FormatError(p, "no such file")
    data = p.read_bytes()
    return Library.from_bytes(data, p), data
