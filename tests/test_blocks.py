"""Clips coded in independent blocks: exact round trips, frame ranges equal to a full decode's frames, targets
held on every frame, the size cost of the default block length, and damaged block indexes refused."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import DATA

import mocapz
from mocapz.codecs.target import ErrorMetric
from mocapz.errors import FormatError, OptionError
from mocapz.format.blocks import INDEX, BlockIndex
from mocapz.format.container import Container
from mocapz.format.entropy import write_uvarint

LOSSLESS_FILES = ["cmu/bvh/09_06.bvh", "cmu/asfamc/01_01.amc", "cmu/c3d/01_01.c3d",
                  "other/markers/btkdata/Gait.trc", "other/markers/btkdata/c3d_samples/Eb015pi.c3d",
                  "other/markers/pyomeca/markers_analogs.c3d"]


def _load(rel: str, frames: int | None = None):
    m = mocapz.load(DATA / rel)
    return m if frames is None else m.slice(0, min(frames, m.n_frames))


@pytest.mark.parametrize("rel", LOSSLESS_FILES)
def test_lossless_blocks_are_exact_and_ranges_equal_the_full_decode(rel: str) -> None:
    m = _load(rel, 400)
    data = mocapz.compress(m, "lossless", block=64)
    assert Container.from_bytes(data).blocked
    full = mocapz.decompress(data)
    assert np.array_equal(full.values, m.values, equal_nan=True)
    n = m.n_frames
    for a, b in [(0, 1), (63, 65), (64, 128), (n - 70, n), (n // 2, n // 2 + 20), (0, n)]:
        part = mocapz.decompress(data, frames=slice(a, b))
        assert part.n_frames == b - a
        assert np.array_equal(part.values, full.values[a:b], equal_nan=True), (a, b)
    if "c3d" in full.metadata:  # the C3D extras cut alike: the range written as a C3D is the range's file
        part = mocapz.decompress(data, frames=slice(10, 30))
        assert part.metadata["c3d"].frames == 20


def test_block_index_covers_every_frame_once() -> None:
    for frames, per in [(1, 5), (9, 5), (10, 5), (14, 5), (100, 7), (7, 7)]:
        idx = BlockIndex(frames, per)
        covered = np.concatenate([np.arange(*idx.bounds(i)) for i in range(idx.count)])
        assert np.array_equal(covered, np.arange(frames))
        assert all(idx.bounds(i)[1] - idx.bounds(i)[0] >= min(per, frames) for i in range(idx.count))
        for f in range(frames):
            a, b = idx.bounds(idx.block_of(f))
            assert a <= f < b


def test_default_lossless_block_costs_under_three_percent() -> None:
    m = _load("cmu/bvh/06_13.bvh")
    blocked, whole = mocapz.compress(m, "lossless"), mocapz.compress(m, "lossless", block=0)
    assert Container.from_bytes(blocked).blocked and not Container.from_bytes(whole).blocked
    assert len(blocked) < 1.03 * len(whole)
    a = m.n_frames // 2
    assert np.array_equal(mocapz.decompress(blocked, frames=(a, a + 20)).values, m.values[a:a + 20])


def test_short_clips_stay_in_one_block() -> None:
    m = _load("cmu/bvh/09_06.bvh")  # 142 frames at 120 Hz: under two default blocks
    assert not Container.from_bytes(mocapz.compress(m, "lossless")).blocked


@pytest.mark.parametrize("codec", ["quant", "pga"])
def test_lossy_blocks_meet_the_target_on_every_frame(codec: str) -> None:
    m = _load("cmu/bvh/02_03.bvh")
    data = mocapz.compress(m, codec, block="0.5s", max_error="1cm")
    assert Container.from_bytes(data).blocked
    back = mocapz.decompress(data)
    errors = ErrorMetric(m).of_motion(back)
    assert errors.max_error <= 1.0 / m.unit_cm * (1 + 1e-9)
    a = 55
    assert np.array_equal(mocapz.decompress(data, frames=slice(a, a + 20)).values, back.values[a:a + 20])


def test_frame_ranges_on_a_file_in_one_block() -> None:
    m = _load("cmu/bvh/09_06.bvh")
    data = mocapz.compress(m, "quant")
    full = mocapz.decompress(data)
    assert np.array_equal(mocapz.decompress(data, frames=slice(-20, None)).values, full.values[-20:])
    with pytest.raises(OptionError):
        mocapz.decompress(data, frames=slice(50, 50))
    with pytest.raises(OptionError):
        mocapz.decompress(data, frames=slice(0, 10, 2))


@pytest.mark.parametrize("spec", ["2x", "-1", "1.5", "s", True])
def test_bad_block_lengths_are_refused_before_encoding(spec) -> None:
    with pytest.raises(OptionError, match="block"):
        mocapz.compress(_load("cmu/bvh/09_06.bvh", 10), "lossless", block=spec)


def _reseal(box: Container, sections: dict[str, bytes]) -> bytes:
    return Container(box.codec, box.codec_version, box.layout, sections).to_bytes()


def test_damaged_block_indexes_are_format_errors() -> None:
    m = _load("cmu/bvh/09_06.bvh", 100)
    box = Container.from_bytes(mocapz.compress(m, "lossless", block=40))
    bad = [
        {**box.sections, INDEX: write_uvarint(40) + write_uvarint(3)},  # count not the clip's
        {**box.sections, INDEX: write_uvarint(0) + write_uvarint(2)},  # empty blocks
        {**box.sections, INDEX: box.sections[INDEX] + b"\x00"},  # trailing bytes
        {**box.sections, "7:rep": b"\x01"},  # a block the index does not have
        {**box.sections, "x:rep": b"\x01"},
        {k: v for k, v in box.sections.items() if not k.startswith("1:")},  # a block's sections missing
        {**box.sections, "rep": b"\x01"},  # codec sections outside the blocks
    ]
    for sections in bad:
        with pytest.raises(FormatError):
            mocapz.decompress(_reseal(box, sections))
    data = bytearray(mocapz.compress(m, "lossless", block=0))  # version 2 claimed, no index
    data[4] = 2
    import struct
    import zlib
    data[-4:] = struct.pack("<I", zlib.crc32(bytes(data[:-4])) & 0xFFFFFFFF)
    with pytest.raises(FormatError, match="block index"):
        mocapz.decompress(bytes(data))


def test_cli_block_and_frame_range(tmp_path) -> None:
    from test_cli import assert_one_line_error, mocapz_cli

    src = DATA / "cmu/bvh/05_02.bvh"
    out = tmp_path / "a.mcz"
    res = mocapz_cli("compress", src, "-o", out, "--block", "1s", "-q")
    assert res.returncode == 0, res.stderr
    assert Container.from_bytes(out.read_bytes()).blocked
    res = mocapz_cli("decompress", out, "--frames", "500:520", "-o", tmp_path / "a.bvh", "-q")
    assert res.returncode == 0, res.stderr
    back = mocapz.load(tmp_path / "a.bvh")
    assert np.array_equal(back.values, mocapz.load(src).values[500:520])
    assert_one_line_error(mocapz_cli("compress", src, "-o", tmp_path / "b.mcz", "--block", "2x"), "--block", 2)
    assert not (tmp_path / "b.mcz").exists()


def test_lossy_blocks_keep_the_clip_figures_and_cost_little() -> None:
    """A clip in 2-s blocks is corrected as the whole clip would be (its contacts, its jitter allowance spent
    block after block): the default target, held feet and jitter hold on the whole clip, for a small fixed cost
    per block (each block's levels, scale bytes and first knot row, its step codes where they differ from the
    block before's, which holds at a max-error target since a block's layout is the clip's: 246 B measured on 05_02,
    +13.7 % of its 9.0 kB file at the default target, 305 B on 02_05 and 358 B on 09_12; 132 B on 05_02 before
    contacts took the floor of the last 2 s, which plants its feet on more frames, each held run's residual
    paid again in every block it spans)."""
    m = _load("cmu/bvh/05_02.bvh")
    whole = mocapz.compress(m, "quant")
    data = mocapz.compress(m, "quant", block="2s")
    assert Container.from_bytes(data).blocked
    rep = mocapz.evaluate(m, mocapz.decompress(data))
    assert rep.max_err_cm <= 1.0 + 1e-9
    assert rep.jitter_pct <= 5.0
    assert rep.foot_skate * m.unit_cm <= 0.5
    blocks = math.ceil(m.n_frames / (2 * m.frame_rate))
    assert len(data) - len(whole) <= 300 * blocks


def test_sections_equal_to_the_previous_blocks_are_written_once() -> None:
    """A block's section equal to the block before's (quant's step codes at a max-error target) is an empty
    mark; frame ranges still decode only their blocks and equal the full decode; a mark naming nothing, or
    carrying bytes, is a FormatError."""
    m = _load("cmu/bvh/05_02.bvh", 960)
    data = mocapz.compress(m, "quant", block=120)
    box = Container.from_bytes(data)
    marks = [k for k in box.sections if k.partition(":")[2].startswith("=")]
    assert marks and not any(k.startswith("0:") for k in marks)
    full = mocapz.decompress(data)
    for a, b in [(0, 20), (119, 121), (500, 520), (900, 960)]:
        assert np.array_equal(mocapz.decompress(data, frames=slice(a, b)).values, full.values[a:b]), (a, b)
    first = marks[0]
    block, _, name = first.partition(":")
    bad = [
        {**box.sections, first: b"\x01"},  # a mark carrying bytes
        {**box.sections, f"0:{name}": b""},  # a mark in the first block
        {**box.sections, f"{block}:=c.nothing": b""},  # a mark naming no section of the block before
        {**box.sections, f"{block}:{name[1:]}": box.sections[f"{int(block) - 1}:{name[1:]}"]
         if f"{int(block) - 1}:{name[1:]}" in box.sections else b"\x01"},  # the section and its mark
    ]
    for sections in bad:
        with pytest.raises(FormatError):
            mocapz.decompress(_reseal(box, sections))
