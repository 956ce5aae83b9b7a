"""Pattern libraries (.mczdb): shared databases, one clip decoded alone, growth with repetition, CLI."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import data_path

from mocapz.cli.db import compress_db
from mocapz.cli.main import cli
from mocapz.codecs.patterns.library import Group, code_groups
from mocapz.codecs.patterns.options import settings_from
from mocapz.codecs.patterns.prepare import prepare
from mocapz.codecs.patterns.segments import decode_segments, encode_segments
from mocapz.errors import FormatError, MocapzError, OptionError
from mocapz.format.library import Library
from mocapz.io import load
from mocapz.libraries import assemble, compress_library, describe_library, read_clip
from mocapz.metrics.figures import evaluate

CLIPS = ["cmu/bvh/09_06.bvh", "cmu/bvh/09_01.bvh", "cmu/bvh/02_03.bvh"]


@pytest.fixture(scope="module")
def runs() -> list:
    return [load(data_path(p)) for p in CLIPS]


def test_one_clip_decoded_alone_equals_library_decoding(runs) -> None:
    prep = prepare(runs[0])
    settings = settings_from({"bits": 3, "tolerance": 0.05})
    coded = code_groups(runs, [Group([0, 1, 2], prep)], settings)
    lib = assemble(runs, [m.name for m in runs], coded, settings)
    decoded = coded[0].decoded
    data = lib.to_bytes()
    # drop every other clip's own streams: the chosen clip must not need them
    alone = Library(lib.index, {k: v for k, v in lib.sections.items() if not k.startswith(("c0.", "c2."))})
    for j in (1,):
        clip = read_clip(alone.to_bytes(), runs[j].name)
        np.testing.assert_allclose(clip.channels, decoded[j], atol=1e-9)
        np.testing.assert_allclose(read_clip(data, runs[j].name).channels, clip.channels, atol=0)
    for m in runs:
        assert evaluate(m, read_clip(data, m.name)).arms_cm < 1.0


def test_library_markers_keep_gaps() -> None:
    m = load(data_path("cmu/c3d/01_01.c3d"))
    a = m.with_positions(m.positions[:400])
    b = m.with_positions(m.positions[400:800])
    b.name = "second"
    data = compress_library([a, b], bits=3, tolerance=0.05)
    for clip in (a, b):
        dec = read_clip(data, clip.name)
        assert np.array_equal(dec.missing, clip.missing)
        assert evaluate(clip, dec).arms < 8.0


def test_ratio_grows_when_a_motion_type_repeats(runs) -> None:
    one = runs[0]
    copies = [one] * 4
    single = compress_library([one], bits=3, tolerance=0.05)
    many = compress_library(copies, bits=3, tolerance=0.05)
    r1 = one.raw_bytes / len(single)
    r4 = 4 * one.raw_bytes / len(many)
    assert r4 > 1.5 * r1
    assert describe_library_bytes(many)["clips"] == ["09_06", "09_06_2", "09_06_3", "09_06_4"]


def describe_library_bytes(data: bytes) -> dict:
    lib = Library.from_bytes(data)
    return {"clips": [c["name"] for c in lib.index["clips"]]}


def test_target_holds_for_every_clip(runs) -> None:
    data = compress_library(runs[:2], max_distortion=1.5)
    for m in runs[:2]:
        assert evaluate(m, read_clip(data, m.name)).distortion_pct <= 1.5


def test_single_pattern_database_with_shared_prior_round_trips() -> None:
    """A node whose database has one pattern (Gait.trc's sparse markers) used to crash the range coder."""
    labels, lengths = np.zeros(4, dtype=np.int64), np.array([256, 183, 1, 47])
    data = encode_segments(labels, lengths, 1, np.array([4]))
    back = decode_segments(data, 1, np.array([4]))
    assert np.array_equal(back[0], labels) and np.array_equal(back[1], lengths)


def test_library_mixing_skeletal_clips_and_a_trc_marker_clip(runs) -> None:
    trc = load(data_path("other/markers/btkdata/Gait.trc"))
    data = compress_library([runs[0], trc])
    assert describe_library_bytes(data)["clips"] == ["09_06", trc.name]
    back = read_clip(data, trc.name)
    assert np.array_equal(back.missing, trc.missing)
    assert evaluate(trc, back).arms_cm < 2.0
    assert evaluate(runs[0], read_clip(data, "09_06")).arms_cm < 2.0


def test_target_length_is_resolved_in_each_clips_own_units(runs) -> None:
    """A length target with a unit (2cm) holds for a BVH clip (CMU units) and a marker clip (mm) whatever
    their order (the search used to apply the first clip's file-unit bound to every clip)."""
    m = load(data_path("cmu/c3d/01_01.c3d"))
    markers = m.with_positions(m.positions[:400])
    markers.name = "markers"
    for clips in ([runs[0], markers], [markers, runs[0]]):
        data = compress_library(clips, max_arms="2cm")
        for clip in clips:
            assert evaluate(clip, read_clip(data, clip.name)).arms_cm <= 2.0


def test_bad_libraries_and_clips(tmp_path, runs) -> None:
    data = compress_library(runs[:1], bits=3, tolerance=0.05)
    with pytest.raises(MocapzError, match="no clip named 'walk'.*09_06"):
        read_clip(data, "walk", "lib.mczdb")
    with pytest.raises(FormatError, match="lib.mczdb"):
        read_clip(data[:-10], "09_06", "lib.mczdb")
    with pytest.raises(FormatError, match="not a mocapz library"):
        read_clip(b"MCZ\x1a" + data[4:], "09_06", "x.mczdb")
    with pytest.raises(OptionError):
        compress_library([])
    with pytest.raises(FormatError, match="no such file"):
        describe_library(tmp_path / "missing.mczdb")


def test_cli_compress_db_info_and_clip(tmp_path) -> None:
    cli.add_command(compress_db)
    runner = CliRunner()
    lib = tmp_path / "runs.mczdb"
    inputs = [str(data_path(p)) for p in CLIPS[:2]]
    res = runner.invoke(cli, ["compress-db", *inputs, "-o", str(lib), "--bits", "3", "--tolerance", "0.05",
                              "--weight", "LeftFoot=4", "--json"])
    assert res.exit_code == 0, res.output
    assert lib.exists()
    info = describe_library(lib)
    assert info["clips"] == ["09_06", "09_01"] and info["ratio"] > 10
    out = tmp_path / "09_01.bvh"
    res = runner.invoke(cli, ["decompress", str(lib), "--clip", "09_01", "-o", str(out)])
    assert res.exit_code == 0, res.output
    back = load(out)
    assert back.n_frames == load(data_path(CLIPS[1])).n_frames
    res = runner.invoke(cli, ["compress-db", *inputs, "-o", str(lib)])
    assert res.exit_code != 0  # exists, no -f
    res = runner.invoke(cli, ["compress-db", inputs[0], "-o", str(tmp_path / "x.mczdb"), "--weight", "Nose=2"])
    assert res.exit_code != 0 and isinstance(res.exception, OptionError)


def test_cli_compress_db_parallel_reads_and_bad_clip(tmp_path) -> None:
    """Clips read by two worker processes give the same library bytes; a bad clip is reported and left out."""
    runner = CliRunner()
    inputs = [str(data_path(p)) for p in CLIPS[:2]]
    serial, parallel = tmp_path / "s.mczdb", tmp_path / "p.mczdb"
    assert runner.invoke(cli, ["compress-db", *inputs, "-o", str(serial)]).exit_code == 0
    assert runner.invoke(cli, ["compress-db", *inputs, "-o", str(parallel), "--jobs", "2"]).exit_code == 0
    assert serial.read_bytes() == parallel.read_bytes()
    bad = tmp_path / "bad.bvh"
    bad.write_text(data_path(CLIPS[0]).read_text()[:3000])
    lib = tmp_path / "with_bad.mczdb"
    res = runner.invoke(cli, ["compress-db", *inputs, str(bad), "-o", str(lib)])
    assert res.exit_code == 1 and lib.exists()
    assert describe_library(lib)["clips"] == ["09_06", "09_01"]
