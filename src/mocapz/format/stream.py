"""The streamed ``.mcz`` (container format version 3): written block by block as frames arrive, readable as
bytes arrive, and an ordinary ``.mcz`` once complete (``mocapz.decompress`` reads it).

Byte layout::

    header   magic b"MCZ\\x1a", byte 3, codec name length n, n bytes codec name, codec version,
             uvarint L + L bytes layout header (its frame count 0: the stream's length is not known yet)
    block    byte 1, uvarint frames (>= 1), the block's codec sections (``write_sections``; one equal to the
             previous block's is the empty mark ``"=name"``, :func:`mocapz.format.blocks.thin`),
             CRC-32 (little endian) of the record from its first byte
    repeat   a block whose sections have the names, in order, of the block record before it (a mark ``"=name"``
             counting as ``name``, the empty section ``"<"`` not counted): byte 2 (byte 3: and the section
             ``"<"``, last), uvarint frames (>= 1), per section in that order uvarint 0 for the mark or its
             length + 1, then the sections' bytes in that order, CRC-32 of the record from its first byte (a 1-s
             block of five sections saves about 35 bytes)
    end      byte 0, uvarint total frames (the blocks' sum), clip-wide sections, CRC-32 of every byte of the
             file before it

A reader checks each block's CRC as it arrives (:class:`StreamReader`), and the end record's CRC covers the
whole file as a version-1 file's does.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field

from mocapz.errors import FormatError
from mocapz.format.blocks import CONTINUES, SAME, thicken
from mocapz.format.container import MAGIC, read_sections, write_sections
from mocapz.format.entropy import read_uvarint, write_uvarint

STREAM_VERSION = 3
BLOCK, END, REPEAT, REPEAT_CONTINUES = 1, 0, 2, 3
MAX_BLOCK_FRAMES = 1 << 24


def is_stream(data: bytes) -> bool:
    """True when ``data`` claims to be a streamed ``.mcz`` (format version 3)."""
    return len(data) > 4 and data[4] == STREAM_VERSION


def header_bytes(codec: str, codec_version: int, layout: bytes) -> bytes:
    """The stream's first bytes."""
    name = codec.encode("ascii")
    return MAGIC + bytes([STREAM_VERSION, len(name)]) + name + bytes([codec_version]) + write_uvarint(len(layout)) \
        + layout


def block_bytes(frames: int, sections: dict[str, bytes], names: list[str] | None = None) -> bytes:
    """One block record (``sections`` as written: thinned); ``names``: :func:`names_of` the block record
    before it (None: the first block), a repeat record when they are the same."""
    if names is not None and names_of(sections) == names:
        listed = {k: v for k, v in sections.items() if k != CONTINUES}
        body = bytes([REPEAT_CONTINUES if CONTINUES in sections else REPEAT]) + write_uvarint(frames) \
            + b"".join(write_uvarint(0 if k.startswith(SAME) else len(v) + 1) for k, v in listed.items()) \
            + b"".join(listed.values())
    else:
        body = bytes([BLOCK]) + write_uvarint(frames) + write_sections(sections)
    return body + struct.pack("<I", zlib.crc32(body) & 0xFFFFFFFF)


def names_of(sections: dict[str, bytes]) -> list[str]:
    """A written block's section names in order, a mark ``"=name"`` as ``name``, the empty section ``"<"`` left out
    (what a repeat record repeats)."""
    return [k[len(SAME):] if k.startswith(SAME) else k for k in sections if k != CONTINUES]


def _repeat_sections(buf: memoryview, pos: int, names: list[str] | None) -> tuple[dict[str, bytes], int]:
    """A repeat record's sections as written (marks included) from ``pos`` (after its frame count)."""
    if names is None:
        raise FormatError(None, "corrupted stream (a repeated block with no block before it)")
    lengths = []
    for _ in names:
        n, pos = read_uvarint(buf, pos)
        lengths.append(n)
    if pos + sum(max(n - 1, 0) for n in lengths) > len(buf):
        raise FormatError(None, "truncated stream block")
    sections = {}
    for name, n in zip(names, lengths, strict=True):
        if not n:
            sections[SAME + name] = b""
            continue
        sections[name] = bytes(buf[pos:pos + n - 1])
        pos += n - 1
    return sections, pos


def end_bytes(total: int, sections: dict[str, bytes], crc_before: int) -> bytes:
    """The end record; ``crc_before`` is the running CRC-32 of every byte written before it."""
    body = bytes([END]) + write_uvarint(total) + write_sections(sections)
    return body + struct.pack("<I", zlib.crc32(body, crc_before) & 0xFFFFFFFF)


@dataclass
class Stream:
    """A parsed stream: codec, layout bytes, the blocks' frame counts and sections, the clip-wide sections."""

    codec: str
    codec_version: int
    layout: bytes
    block_frames: list[int] = field(default_factory=list)
    blocks: list[dict[str, bytes]] = field(default_factory=list)
    sections: dict[str, bytes] = field(default_factory=dict)
    complete: bool = False

    @property
    def frames(self) -> int:
        return sum(self.block_frames)


class StreamReader:
    """Parse a stream as its bytes arrive: :meth:`feed` returns the blocks completed by the new bytes.
    ``keep=False``: the blocks are not kept in :attr:`stream` (a live decoder's memory stays bounded)."""

    def __init__(self, keep: bool = True) -> None:
        self.keep = keep
        self.buffer = bytearray()
        self.pos = 0  # bytes of ``buffer`` already parsed
        self.stream: Stream | None = None
        self.crc = 0
        self.last: dict[str, bytes] | None = None  # the previous block's sections (:func:`.blocks.thicken`)
        self.names: list[str] | None = None  # the previous block's section names as written (a repeat record's)

    @property
    def pending(self) -> int:
        """Bytes received and not yet part of a complete record."""
        return len(self.buffer) - self.pos

    def feed(self, data: bytes) -> list[tuple[int, dict[str, bytes]]]:
        """Add bytes; return ``(frames, sections)`` of every block they complete (FormatError if damaged)."""
        if self.stream is not None and self.stream.complete and data:
            raise FormatError(None, "bytes after the end of the stream")
        if self.pos:
            del self.buffer[:self.pos]
            self.pos = 0
        self.buffer += data
        out = []
        while True:
            view = memoryview(self.buffer)[self.pos:]
            try:
                got = self._next(view)
            finally:
                view.release()
            if got is None:
                return out
            used, block = got
            self.pos += used
            if block is not None:
                out.append(block)

    def _next(self, buf: memoryview) -> tuple[int, tuple[int, dict[str, bytes]] | None] | None:
        """``(bytes used, the block or None)`` of the next complete record, None if it is not all here."""
        try:
            if self.stream is None:
                return self._header(buf)
            if self.stream.complete or not len(buf):
                return None
            kind = buf[0]
            frames, pos = read_uvarint(buf, 1)
            if kind in (REPEAT, REPEAT_CONTINUES):
                sections, pos = _repeat_sections(buf, pos, self.names)
                if kind == REPEAT_CONTINUES:
                    sections[CONTINUES] = b""
            else:
                sections, pos = read_sections(buf, pos, "stream block")
        except FormatError as exc:
            if "truncated" in exc.problem:
                return None  # wait for more bytes
            raise
        if pos + 4 > len(buf):
            return None
        (crc,) = struct.unpack("<I", buf[pos:pos + 4])
        if kind in (BLOCK, REPEAT, REPEAT_CONTINUES):
            if zlib.crc32(buf[:pos]) & 0xFFFFFFFF != crc:
                raise FormatError(None, "corrupted stream block (checksum mismatch)")
            if not 1 <= frames <= MAX_BLOCK_FRAMES:
                raise FormatError(None, f"corrupted stream block ({frames} frames)")
        elif kind == END:
            if zlib.crc32(buf[:pos], self.crc) & 0xFFFFFFFF != crc:
                raise FormatError(None, "corrupted or truncated stream (checksum mismatch)")
            if frames != self.stream.frames:
                raise FormatError(None, f"corrupted stream (end says {frames} frames, its blocks hold "
                                        f"{self.stream.frames})")
        else:
            raise FormatError(None, f"corrupted stream (record kind {kind})")
        self.crc = zlib.crc32(buf[:pos + 4], self.crc)
        if kind == END:
            self.stream.sections = sections
            self.stream.complete = True
            return pos + 4, None
        self.names = names_of(sections)
        sections = self.last = thicken(self.last, sections)
        self.stream.block_frames.append(frames)
        if self.keep:
            self.stream.blocks.append(sections)
        return pos + 4, (frames, sections)

    def _header(self, buf: memoryview) -> tuple[int, None] | None:
        if len(buf) < 7:
            return None
        if bytes(buf[:4]) != MAGIC or buf[4] != STREAM_VERSION:
            raise FormatError(None, "not a streamed mocapz .mcz (bad magic bytes or version)")
        n = buf[5]
        pos = 6 + n
        if pos + 1 > len(buf):
            return None
        codec = bytes(buf[6:pos]).decode("ascii", errors="replace")
        version = buf[pos]
        ln, pos = read_uvarint(buf, pos + 1)
        if pos + ln > len(buf):
            return None
        self.stream = Stream(codec, version, bytes(buf[pos:pos + ln]))
        self.crc = zlib.crc32(buf[:pos + ln])
        return pos + ln, None


def read_stream(data: bytes) -> Stream:
    """A complete stream (FormatError if truncated, damaged or followed by other bytes)."""
    reader = StreamReader()
    reader.feed(data)
    if reader.stream is None or not reader.stream.complete:
        raise FormatError(None, "truncated streamed .mcz file (no end record)")
    if reader.pending:
        raise FormatError(None, "corrupted streamed .mcz file (bytes after the end record)")
    return reader.stream
