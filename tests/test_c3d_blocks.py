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


@pytest.mark.parametrize("rel", FILES[2:])
def test_a_reader_keeps_one_blocks_extras_and_gives_each_range_its_own(rel: str) -> None:
    """A C3D clip in one block (the lossy codecs' default) has its extras' words xz-packed whole: a reader decodes
    them once and gives every range the extras ``decompress(frames=)`` gives (header, parameters, every word),
    its own copy (a range's arrays changed by the caller change no later range), and the whole clip's as before."""
    src = mocapz.load(data_path(rel))
    data = mocapz.compress(src, "quant")
    assert "c3d.blk" not in Container.from_bytes(data).sections
    reader = mocapz.open(data)
    n = src.n_frames
    for a, b in ((n // 2, n // 2 + 20), (0, 1), (n - 7, n), (n // 2, n // 2 + 20), (5, n - 5)):
        part = reader[a:b]
        _same(part, mocapz.decompress(data, frames=slice(a, b)))
        _same(part, src.slice(a, b))
        part.metadata["c3d"].analog_words[:] = -1
        part.metadata["c3d"].residual_words[:] = -1
    assert "c3d" in reader._memo
    _same(reader[0:n], src)
