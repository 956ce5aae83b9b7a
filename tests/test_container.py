"""The .mcz container: byte layout (as docs/format.md describes it) and robustness against bad bytes.

Whatever the bytes, ``mocapz.decompress`` either returns a motion or raises :class:`mocapz.FormatError`;
never another exception type.
"""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
import zstandard
from conftest import data_path

import mocapz
from mocapz import FormatError
from mocapz.format.container import FORMAT_VERSION, MAGIC, Container
from mocapz.format.layout import _DICT, decode_layout, encode_layout, layout_dict
from mocapz.io.bvh import read_bvh
from mocapz.model.motion import Motion


@pytest.fixture(scope="module")
def clip() -> Motion:
    """The first 20 frames of CMU 09_06."""
    return read_bvh(data_path("cmu/bvh/09_06.bvh")).slice(0, 20)


@pytest.fixture(scope="module")
def small(clip: Motion) -> bytes:
    """A small lossless .mcz of :func:`clip`."""
    return mocapz.compress(clip, codec="lossless")


def _uvarint(buf: bytes, pos: int) -> tuple[int, int]:
    """LEB128 unsigned varint at ``pos``: (value, next position). Written apart from mocapz.format.entropy."""
    value = shift = 0
    while True:
        b = buf[pos]
        pos += 1
        value |= (b & 0x7F) << shift
        shift += 7
        if b < 0x80:
            return value, pos


def _with_crc(body: bytes) -> bytes:
    """``body`` (without checksum) followed by its CRC-32, little endian."""
    return body + struct.pack("<I", zlib.crc32(body) & 0xFFFFFFFF)


def _refresh_crc(data: bytes) -> bytes:
    """Recompute the trailing checksum of a (modified) container."""
    return _with_crc(data[:-4])


def _decodes_or_format_error(data: bytes) -> str:
    """Decompress ``data``: "ok", "format" (FormatError) or the name of any other exception raised."""
    try:
        mocapz.decompress(data)
    except FormatError:
        return "format"
    except Exception as exc:  # noqa: BLE001 - the point of the test
        return f"{type(exc).__name__}: {str(exc)[:80]}"
    return "ok"


# ----------------------------------------------------------------------------------------- layout
def test_byte_layout_as_documented(small: bytes, clip: Motion) -> None:
    """Parse the container by hand, following docs/format.md byte by byte."""
    assert small[:4] == b"MCZ\x1a" == MAGIC
    assert small[4] == FORMAT_VERSION == 1
    n = small[5]
    assert small[6 : 6 + n] == b"lossless"
    assert small[6 + n] == 2  # lossless codec version
    ln, pos = _uvarint(small, 7 + n)
    layout = small[pos : pos + ln]
    zlen, zpos = _uvarint(layout, 0)
    assert layout[zpos : zpos + 4] == b"\x28\xb5\x2f\xfd"  # a zstd frame
    text = zstandard.ZstdDecompressor(dict_data=_DICT).decompress(layout[zpos : zpos + zlen])
    d = json.loads(text)
    assert d["kind"] == "skeleton" and d["frames"] == 20 and d["names"] == clip.skeleton.names
    # offsets travel as zig-zag varints of round(value * 10**num_dec) after the JSON
    assert d["offsets"] is None and d["num_dec"] == 5
    block = layout[zpos + zlen :]
    vals, bpos = [], 0
    while bpos < len(block):
        v, bpos = _uvarint(block, bpos)
        vals.append((v >> 1) ^ -(v & 1))
    assert len(vals) == 3 * (clip.skeleton.n_joints + len(clip.skeleton.end_sites))
    assert np.array_equal(np.array(vals[: 3 * clip.skeleton.n_joints]).reshape(-1, 3) / 1e5, clip.skeleton.offsets)
    assert d["channels"][0] == "XposYposZposZrotYrotXrot" and d["orders"][1] == "ZYX"
    pos += ln
    count, pos = _uvarint(small, pos)
    sections: dict[str, bytes] = {}
    for _ in range(count):
        k = small[pos]
        key = small[pos + 1 : pos + 1 + k].decode("ascii")
        m, pos = _uvarint(small, pos + 1 + k)
        sections[key] = small[pos : pos + m]
        pos += m
    assert pos == len(small) - 4
    assert struct.unpack("<I", small[-4:])[0] == zlib.crc32(small[:-4])
    assert [k for k in sections if k not in ("exc", "negz")] == ["rep", "const", "head", "coef", "res"]
    box = Container.from_bytes(small)
    assert box.codec == "lossless" and box.codec_version == 2 and box.layout == layout
    assert box.sections == sections


def test_layout_header_is_small_and_exact(clip: Motion) -> None:
    """A CMU skeleton's layout costs a few hundred bytes thanks to the dictionary, and reads back exactly."""
    raw = encode_layout(clip)
    assert len(raw) < 600
    plain = zstandard.ZstdCompressor(level=19).compress(json.dumps(layout_dict(clip), separators=(",", ":")).encode())
    assert len(raw) < len(plain)
    d = decode_layout(raw)
    assert d == json.loads(json.dumps(layout_dict(clip)))
    assert np.array_equal(np.array(d["offsets"]), clip.skeleton.offsets)


def test_container_round_trip() -> None:
    sections = {"a": b"", "bb": b"x" * 300, "c" * 255: bytes(range(256))}
    box = Container("somecodec", 7, b"layout" * 50, sections)
    data = box.to_bytes()
    back = Container.from_bytes(data)
    assert (back.codec, back.codec_version, back.layout, back.sections) == ("somecodec", 7, b"layout" * 50, sections)
    assert Container.from_bytes(Container("x", 0, b"", {}).to_bytes()).sections == {}


def test_decoded_motion_keeps_everything(small: bytes, clip: Motion) -> None:
    back = mocapz.decompress(small)
    assert isinstance(back, Motion)
    assert np.array_equal(back.channels, clip.channels)
    assert back.name == clip.name and back.frame_rate == clip.frame_rate and back.source_format == "bvh"
    assert np.array_equal(back.decimals, clip.decimals)
    a, b = clip.skeleton, back.skeleton
    assert b.names == a.names and np.array_equal(b.parents, a.parents) and np.array_equal(b.offsets, a.offsets)
    assert b.channels == a.channels and b.rotation_order == a.rotation_order and b.unit_cm == a.unit_cm
    assert [(j, list(o), n) for j, o, n in b.end_sites] == [(j, list(o), n) for j, o, n in a.end_sites]
    assert back.metadata["frame_time"] == clip.metadata["frame_time"]


# ------------------------------------------------------------------------------------ bad bytes
@pytest.mark.parametrize("data", [
    b"",
    b"M",
    b"MCZ",
    MAGIC,
    MAGIC + b"\x01",
    b"HIERARCHY\nROOT Hips\n{\n",
    bytes(64),
    b"\xff" * 1000,
], ids=["empty", "1byte", "3bytes", "magic", "magic+version", "bvh-text", "zeros", "ff"])
def test_garbage(data: bytes) -> None:
    with pytest.raises(FormatError):
        mocapz.decompress(data)


def test_random_garbage() -> None:
    rng = np.random.default_rng(7)
    for n in (5, 11, 12, 50, 400, 5000):
        junk = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        assert _decodes_or_format_error(junk) == "format"
        assert _decodes_or_format_error(MAGIC + junk) == "format"
        assert _decodes_or_format_error(_with_crc(MAGIC + b"\x01" + junk)) == "format"


def test_every_truncation(small: bytes) -> None:
    bad = {n: r for n in range(len(small)) if (r := _decodes_or_format_error(small[:n])) != "format"}
    assert bad == {}


def test_every_flipped_byte(small: bytes) -> None:
    """One flipped byte anywhere (checksum included) is caught."""
    bad = {}
    for i in range(len(small)):
        for x in (0x01, 0xFF):
            b = bytearray(small)
            b[i] ^= x
            if (r := _decodes_or_format_error(bytes(b))) != "format":
                bad[(i, x)] = r
    assert bad == {}


def test_flipped_byte_with_valid_checksum(small: bytes) -> None:
    """Corruption the checksum cannot see (a writer bug, a crafted file): a motion or FormatError, nothing else."""
    positions = list(range(0, 64)) + list(range(64, len(small) - 4, 11))
    bad = {}
    for i in positions:
        for x in (0x01, 0x80, 0xFF):
            b = bytearray(small)
            b[i] ^= x
            r = _decodes_or_format_error(_refresh_crc(bytes(b)))
            if r not in ("ok", "format"):
                bad[(i, x)] = r
    assert bad == {}


def test_appended_bytes(small: bytes) -> None:
    assert _decodes_or_format_error(small + b"\x00") == "format"
    assert _decodes_or_format_error(_with_crc(small[:-4] + b"\x00")) == "format"  # bytes after the sections


def test_wrong_magic(small: bytes) -> None:
    for magic in (b"MCZ\x1b", b"mcz\x1a", b"PK\x03\x04"):
        with pytest.raises(FormatError, match="magic"):
            mocapz.decompress(_refresh_crc(magic + small[4:]))


@pytest.mark.parametrize("version", [0, 4, 255])
def test_unsupported_version(small: bytes, version: int) -> None:
    data = _refresh_crc(small[:4] + bytes([version]) + small[5:])
    with pytest.raises(FormatError, match=f"unsupported .mcz format version {version}"):
        mocapz.decompress(data)


def test_unknown_codec_and_codec_version(small: bytes) -> None:
    box = Container.from_bytes(small)
    with pytest.raises(FormatError, match="unknown codec 'nosuch'"):
        mocapz.decompress(Container("nosuch", 1, box.layout, box.sections).to_bytes())
    with pytest.raises(FormatError, match="version 9"):
        mocapz.decompress(Container("lossless", 9, box.layout, box.sections).to_bytes())


def test_errors_name_the_file(small: bytes) -> None:
    with pytest.raises(FormatError) as err:
        mocapz.decompress(small[:-1], Path("some/dir/clip.mcz"))
    assert str(err.value).startswith("some/dir/clip.mcz: ") and err.value.path == "some/dir/clip.mcz"
    box = Container.from_bytes(small)
    sections = dict(box.sections, res=b"\x01\x05")
    with pytest.raises(FormatError) as err:
        mocapz.decompress(Container("lossless", 2, box.layout, sections).to_bytes(), "x.mcz")
    assert str(err.value).startswith("x.mcz: ")


@pytest.mark.parametrize("name", ["rep", "head", "const", "coef", "res"])
def test_missing_empty_or_garbage_section(small: bytes, name: str) -> None:
    box = Container.from_bytes(small)
    missing = {k: v for k, v in box.sections.items() if k != name}
    for sections in (missing, dict(box.sections, **{name: b""}), dict(box.sections, **{name: b"\x07garbage" * 3})):
        r = _decodes_or_format_error(Container("lossless", 2, box.layout, sections).to_bytes())
        allowed = ("format", "ok") if name == "rep" else ("format",)  # any rep byte names a representation
        assert r in allowed, r
    with pytest.raises(FormatError, match="missing section"):
        mocapz.decompress(Container("lossless", 2, box.layout, missing).to_bytes())


def _relayout(small: bytes, edit: dict[str, object]) -> bytes:
    """``small`` with its layout JSON changed by ``edit`` (valid zstd, valid checksum)."""
    box = Container.from_bytes(small)
    d = decode_layout(box.layout)
    d.update(edit)
    text = json.dumps(d).encode()
    layout = zstandard.ZstdCompressor(dict_data=_DICT).compress(text)
    return Container(box.codec, box.codec_version, layout, box.sections).to_bytes()


@pytest.mark.parametrize("edit", [
    {"kind": "nothing"},
    {"kind": "markers"},
    {"frames": -5},
    {"frames": "abc"},
    {"frames": 19},
    {"frames": 21},
    {"channels": ["Qpos"] * 31},
    {"names": ["Hips"]},
    {"parents": [5] * 31},
    {"offsets": [[1, 2]]},
    {"decimals": None},
    {"decimals": [4, 4]},
    {"frame_rate": "fast"},
], ids=lambda e: "-".join(f"{k}={v}"[:20] for k, v in e.items()))
def test_inconsistent_layout(small: bytes, edit: dict[str, object]) -> None:
    assert _decodes_or_format_error(_relayout(small, edit)) == "format"


def test_layout_not_json(small: bytes) -> None:
    box = Container.from_bytes(small)
    for raw in (zstandard.ZstdCompressor(dict_data=_DICT).compress(b"not json {"),
                zstandard.ZstdCompressor(dict_data=_DICT).compress(b"[1, 2]"),
                zstandard.ZstdCompressor().compress(b'{"kind": "skeleton"}'),  # no dictionary: still valid zstd
                b"\x28\xb5\x2f\xfd\x00", b""):
        assert _decodes_or_format_error(Container("lossless", 2, raw, box.sections).to_bytes()) == "format"


# --------------------------------------------------------------------- crafted sizes (memory bombs)
def _zstd_frame_claiming(size: int) -> bytes:
    """A zstd frame of 8 zero bytes whose header claims ``size`` bytes of content (8-byte size field)."""
    frame = zstandard.ZstdCompressor(level=19).compress(bytes(8))
    assert frame[4] == 0x20  # single segment, 1-byte content size
    return frame[:4] + bytes([0xE0]) + struct.pack("<Q", size) + frame[6:]


def test_layout_claiming_huge_size(small: bytes) -> None:
    """A layout frame that claims 1 TiB of JSON must be a FormatError (not a MemoryError)."""
    box = Container.from_bytes(small)
    data = Container("lossless", 2, _zstd_frame_claiming(1 << 40), box.sections).to_bytes()
    assert _decodes_or_format_error(data) == "format"


def test_section_claiming_huge_size(small: bytes) -> None:
    """A byte-plane stream (entropy.pack_uint64) whose zstd frame claims 1 TiB: FormatError."""
    box = Container.from_bytes(small)
    head = b"\x08\x01" + _zstd_frame_claiming(1 << 40)  # 8 values, 1 byte each
    data = Container("lossless", 2, box.layout, dict(box.sections, head=head)).to_bytes()
    assert _decodes_or_format_error(data) == "format"


def test_layout_claiming_huge_frame_count(small: bytes) -> None:
    """A layout announcing 10**12 frames (the sections hold 20): FormatError, not a 700 TiB allocation."""
    assert _decodes_or_format_error(_relayout(small, {"frames": 10**12})) == "format"
