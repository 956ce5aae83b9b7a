"""A C3D clip coded in blocks has its analogs, residuals, tracks and stored words in the same blocks (issue 12):
a frame range gives exactly the extras of those frames in the whole file, decoding only its blocks, and the
file it writes is the source's frames cut alike."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.format.container import Container

FILES = ["other/markers/pyomeca/markers_analogs.c3d", "other/markers/btkdata/c3d_samples/PiG_Motion-FlatFoot-Full.c3d",
         "cmu/c3d/01_01.c3d", "other/markers/btkdata/c3d_samples/Eb015vr.c3d"]
WORDS = ("residual_words", "track_words", "analog_words", "fix_mask", "fix_words")


def _same(a: mocapz.MarkerMotion, b: mocapz.MarkerMotion) -> None:
    x, y = a.metadata["c3d"], b.metadata["c3d"]
    assert x.header == y.header and x.params == y.params
    for key in WORDS:
        np.testing.assert_array_equal(getattr(x, key), getattr(y, key), err_msg=key)


@pytest.mark.parametrize("rel", FILES)
def test_a_range_gives_the_extras_of_its_frames(rel: str, tmp_path: Path) -> None:
    src = mocapz.load(data_path(rel))
    data = mocapz.compress(src, "lossless", block=64)
    sections = Container.from_bytes(data).sections
    count = src.n_frames // 64
    assert "c3d.blk" in sections and f"c3d.ana.{count - 1}" in sections and "c3d.ana" not in sections
    whole = mocapz.decompress(data)
    _same(whole, src)
    for a, b in ((0, 1), (63, 65), (src.n_frames - 20, src.n_frames), (10, src.n_frames - 10)):
        part = mocapz.decompress(data, frames=slice(a, b))
        expected = mocapz.load(data_path(rel)).slice(a, b)
        _same(part, expected)
        np.testing.assert_array_equal(part.positions, src.positions[a:b])
    mocapz.save(mocapz.decompress(data, frames=slice(70, 90)), tmp_path / "part.c3d")
    mocapz.save(src.slice(70, 90), tmp_path / "ref.c3d")
    assert (tmp_path / "part.c3d").read_bytes() == (tmp_path / "ref.c3d").read_bytes()


def test_blocks_cost_little_and_one_block_keeps_the_whole_clip_sections() -> None:
    src = mocapz.load(data_path(FILES[0]))
    one = Container.from_bytes(mocapz.compress(src, "lossless", block=0)).sections
    assert {k for k in one if k.startswith("c3d.")} == {"c3d.file", "c3d.res", "c3d.trk", "c3d.ana", "c3d.fix"}
    blocked = Container.from_bytes(mocapz.compress(src, "lossless")).sections  # the default blocks
    size = sum(len(v) for k, v in blocked.items() if k.startswith("c3d."))
    assert size < 1.03 * sum(len(v) for k, v in one.items() if k.startswith("c3d."))


def test_a_lossy_codec_in_blocks_keeps_the_extras_per_block() -> None:
    src = mocapz.load(data_path(FILES[1])).slice(0, 200)
    data = mocapz.compress(src, "quant", max_error="1cm", block=50)
    part = mocapz.decompress(data, frames=slice(120, 160))
    _same(part, src.slice(120, 160))
