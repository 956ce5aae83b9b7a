"""A stream's repeat records: a block whose sections have the names of the block before it writes only their
lengths. Real streams use them, they make the stream smaller, a stream written with full records only (as before
them) still reads to the same values, and damaged or misplaced repeat records are FormatErrors."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.errors import FormatError
from mocapz.format import stream as framing
from mocapz.format.blocks import thin


def _header_end(data: bytes) -> int:
    """Where a stream's first block record starts."""
    s = framing.read_stream(data)
    return len(framing.header_bytes(s.codec, s.codec_version, s.layout))


def _records(data: bytes) -> list[int]:
    """The kinds of a stream's block records, in order: fed to the reader byte by byte, a record ends at the
    byte that completes its block."""
    reader = framing.StreamReader()
    start = _header_end(data)
    reader.feed(data[:start])
    kinds = []
    for i in range(start, len(data)):
        if reader.feed(data[i:i + 1]):
            kinds.append(data[start])
            start = i + 1
    return kinds


def _full_records(data: bytes) -> bytes:
    """The same stream with every block written as a full record (no repeat record)."""
    s = framing.read_stream(data)
    out, last = bytearray(data[:_header_end(data)]), None
    for frames, sections in zip(s.block_frames, s.blocks, strict=True):
        out += framing.block_bytes(frames, thin(last, sections))
        last = sections
    return bytes(out + framing.end_bytes(s.frames, s.sections, zlib.crc32(out)))


@pytest.fixture(scope="module")
def quant_stream():
    m = mocapz.load(data_path("cmu/bvh/02_05.bvh")).slice(0, 1200)
    enc = mocapz.StreamEncoder(m, "quant", max_error="1cm")
    return m, enc.write(m.values) + enc.close()


def test_continued_blocks_are_repeat_records_and_cost_less(quant_stream) -> None:
    m, data = quant_stream
    kinds = _records(data)
    assert len(kinds) == 10 and kinds[0] == framing.BLOCK
    s = framing.read_stream(data)
    written = [thin(s.blocks[i - 1] if i else None, b) for i, b in enumerate(s.blocks)]
    names = [framing.names_of(w) for w in written]
    # a repeat record exactly where the names repeat (the empty section "<" aside: it is the record's kind),
    # i.e. every block but the first
    assert kinds == [(framing.REPEAT_CONTINUES if "<" in written[i] else framing.REPEAT)
                     if i and names[i] == names[i - 1] else framing.BLOCK for i in range(10)]
    assert kinds.count(framing.REPEAT_CONTINUES) == 8 and kinds.count(framing.REPEAT) == 1  # the last: alone
    full = _full_records(data)
    assert len(full) - len(data) >= 30 * 9  # about 35 bytes a block
    a, b = mocapz.decompress(data), mocapz.decompress(full)
    assert np.array_equal(a.values, b.values)
    assert mocapz.evaluate(m, a).max_err_cm <= 1.0 + 1e-9


def test_repeat_records_decode_as_bytes_arrive(quant_stream) -> None:
    _, data = quant_stream
    whole = mocapz.decompress(data).values
    dec = mocapz.StreamDecoder()
    got = []
    for i in range(0, len(data), 37):
        got += dec.feed(data[i:i + 37])
    assert dec.complete and np.array_equal(np.concatenate([g.values for g in got]), whole)


def test_misplaced_or_damaged_repeat_records_are_format_errors(quant_stream) -> None:
    _, data = quant_stream
    start = _header_end(data)
    # the first block rewritten as a repeat record: there is no record before it to take the names from
    s = framing.read_stream(data)
    first = framing.block_bytes(s.block_frames[0], s.blocks[0], list(s.blocks[0]))
    assert first[0] == framing.REPEAT
    rest = data[start + len(framing.block_bytes(s.block_frames[0], s.blocks[0])):]
    with pytest.raises(FormatError, match="no block before"):
        mocapz.decompress(data[:start] + first + rest)
    # a length in a repeat record (the third block's) changed, its checksum fixed: the sections no longer parse
    records = [framing.block_bytes(s.block_frames[i], thin(s.blocks[i - 1] if i else None, s.blocks[i]),
                                   framing.names_of(thin(s.blocks[i - 2] if i > 1 else None, s.blocks[i - 1]))
                                   if i else None)
               for i in range(3)]
    assert [r[0] for r in records] == [framing.BLOCK, framing.REPEAT_CONTINUES, framing.REPEAT_CONTINUES]
    at = start + len(records[0]) + len(records[1])
    assert data[at:at + len(records[2])] == records[2]
    for pos, flip in ((3, 0x01), (3, 0x7F), (4, 0x02)):  # byte 0 kind, 1-2 frames (128), 3.. the lengths
        bad = bytearray(records[2])
        bad[pos] ^= flip
        bad[-4:] = struct.pack("<I", zlib.crc32(bytes(bad[:-4])) & 0xFFFFFFFF)
        with pytest.raises(FormatError):
            mocapz.decompress(data[:at] + bytes(bad) + data[at + len(records[2]):])
