"""The ``.mcz`` container: magic, version, codec id, layout header, payload sections, checksum.

Byte layout (documented in docs/format.md)::

    offset  size  field
    0       4     magic b"MCZ\\x1a"
    4       1     container format version (1; 2: the clip is coded in blocks, see mocapz.format.blocks)
    5       1     codec name length n
    6       n     codec name, ASCII (e.g. "lossless", "pga", "patterns")
    6+n     1     codec version
    ...     var   uvarint layout length L, then L bytes of zstd-compressed JSON layout
    ...     var   uvarint section count S, then S times:
                    1 byte name length k, k bytes ASCII name, uvarint length m, m bytes payload
    end-4   4     CRC-32 (zlib, little endian) of every byte before it
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from mocapz.errors import FormatError
from mocapz.format.blocks import INDEX
from mocapz.format.entropy import read_uvarint, write_uvarint

MAGIC = b"MCZ\x1a"
FORMAT_VERSION = 1  # a clip in one piece
BLOCKED_VERSION = 2  # a clip in independent blocks (the section ``blk`` indexes them)


@dataclass
class Container:
    """Parsed container: codec name/version, raw layout bytes and named payload sections."""

    codec: str
    codec_version: int
    layout: bytes
    sections: dict[str, bytes] = field(default_factory=dict)

    @property
    def blocked(self) -> bool:
        """True when the clip is coded in blocks (format version 2)."""
        return INDEX in self.sections

    def to_bytes(self) -> bytes:
        name = self.codec.encode("ascii")
        out = bytearray(MAGIC)
        version = BLOCKED_VERSION if self.blocked else FORMAT_VERSION
        out += bytes([version, len(name)]) + name + bytes([self.codec_version])
        out += write_uvarint(len(self.layout)) + self.layout
        out += write_sections(self.sections)
        return seal(out)

    @classmethod
    def from_bytes(cls, data: bytes, path: str | Path | None = None) -> Container:
        try:
            return cls._parse(data)
        except FormatError as exc:
            raise FormatError(path, exc.problem) from None

    @classmethod
    def _parse(cls, data: bytes) -> Container:
        if len(data) < 4 or data[:4] != MAGIC:
            raise FormatError(None, "not a mocapz .mcz file (bad magic bytes)")
        if len(data) < 11:
            raise FormatError(None, "truncated .mcz file")
        (crc,) = struct.unpack("<I", data[-4:])
        if zlib.crc32(data[:-4]) & 0xFFFFFFFF != crc:
            raise FormatError(None, "corrupted or truncated .mcz file (checksum mismatch)")
        version = data[4]
        if version not in (FORMAT_VERSION, BLOCKED_VERSION):
            raise FormatError(None, f"unsupported .mcz format version {version} (this mocapz reads "
                                    f"{FORMAT_VERSION} and {BLOCKED_VERSION})")
        body = memoryview(data)[:-4]
        n = body[5]
        pos = 6 + n
        if pos + 1 > len(body):
            raise FormatError(None, "truncated .mcz header")
        codec = bytes(body[6:pos]).decode("ascii", errors="replace")
        codec_version = body[pos]
        pos += 1
        ln, pos = read_uvarint(body, pos)
        layout = bytes(body[pos : pos + ln])
        pos += ln
        sections, pos = read_sections(body, pos, ".mcz")
        if pos != len(body) or len(layout) != ln:
            raise FormatError(None, "corrupted .mcz file (length mismatch)")
        box = cls(codec, codec_version, layout, sections)
        if box.blocked != (version == BLOCKED_VERSION):
            raise FormatError(None, f"corrupted .mcz file (format version {version} with"
                                    f"{'' if box.blocked else 'out'} a block index)")
        return box


def write_sections(sections: dict[str, bytes]) -> bytes:
    """``uvarint count``, then per section: name length byte, ASCII name, uvarint length, payload."""
    out = bytearray(write_uvarint(len(sections)))
    for key, payload in sections.items():
        k = key.encode("ascii")
        out += bytes([len(k)]) + k + write_uvarint(len(payload)) + payload
    return bytes(out)


def read_sections(body: memoryview, pos: int, what: str) -> tuple[dict[str, bytes], int]:
    """Inverse of :func:`write_sections` starting at ``pos``; returns the sections and the end position."""
    count, pos = read_uvarint(body, pos)
    sections: dict[str, bytes] = {}
    for _ in range(count):
        if pos >= len(body):
            raise FormatError(None, f"truncated {what} sections")
        k = body[pos]
        key = bytes(body[pos + 1 : pos + 1 + k]).decode("ascii", errors="replace")
        pos += 1 + k
        m, pos = read_uvarint(body, pos)
        if pos + m > len(body):
            raise FormatError(None, f"truncated {what} section {key!r}")
        sections[key] = bytes(body[pos : pos + m])
        pos += m
    return sections, pos


def seal(out: bytes | bytearray) -> bytes:
    """Append the CRC-32 (zlib, little endian) of everything before it."""
    return bytes(out) + struct.pack("<I", zlib.crc32(out) & 0xFFFFFFFF)
