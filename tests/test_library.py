"""Pattern libraries (.mczdb): shared databases, one clip decoded alone, growth with repetition, CLI."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import data_path

from mocapz.cli.db import compress_db
from mocapz.cli.main import cli
from mocapz.codecs.patterns.segments import decode_segments, encode_segments
from mocapz.errors import FormatError, MocapzError, OptionError
from mocapz.format.library import Library
from mocapz.io import load
from mocapz.libraries import compress_library, decode_clip, describe_library, read_clip
from mocapz.metrics.figures import evaluate

CLIPS = ["cmu/bvh/09_06.bvh", "cmu/bvh/09_01.bvh", "cmu/bvh/02_03.bvh"]


@pytest.fixture(scope="module")
def runs() -> list:
    return [load(data_path(p)) for p in CLIPS]


def test_one_clip_decoded_alone_equals_library_decoding(runs, tmp_path) -> None:
    data = compress_library(runs, bits=3, tolerance=0.05)
    lib = Library.from_bytes(data)
    # drop every other clip's own streams: the chosen clip must not need them
    alone = Library(lib.index, {k: v for k, v in lib.sections.items() if not k.startswith(("c0.", "c2."))})
    clip = decode_clip(alone, runs[1].name)
    np.testing.assert_allclose(read_clip(data, runs[1].name).channels, clip.channels, atol=0)
    for m in runs:
        assert evaluate(m, read_clip(data, m.name)).max_err_cm <= 1.0  # the default target, as for one clip


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
    # each copy carries its own correction (the default target, 1 cm, holds on every clip): 1.46x measured
    assert r4 > 1.35 * r1
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
    assert info["clips"] == ["09_06", "09_01"] and info["ratio"] > 8  # 8.8 with the 1-cm correction
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


# ------------------------------------------------------------------ every lossy codec's library mode
SAME_SKELETON = ["cmu/bvh/09_06.bvh", "cmu/bvh/09_01.bvh"]  # subject 9: one skeleton, stored once


@pytest.fixture(scope="module")
def pga_lib(runs) -> bytes:
    return compress_library(runs[:2], codec="pga", max_error="1cm")


def test_pga_and_quant_libraries_meet_every_target_and_beat_the_single_files(runs, pga_lib) -> None:
    """Each clip decoded from the library holds max error 1 cm on every joint and end site of every frame; the
    library is smaller than the single files (one skeleton, one pose model)."""
    import mocapz

    for codec, data in (("pga", pga_lib), ("quant", compress_library(runs[:2], codec="quant", max_error="1cm"))):
        singles = sum(len(mocapz.compress(m, codec=codec, max_error="1cm")) for m in runs[:2])
        assert len(data) < singles, (codec, len(data), singles)
        lib = Library.from_bytes(data)
        assert len(lib.index["skeletons"]) == 1 and len(lib.index["groups"]) == 1
        for m in runs[:2]:
            assert evaluate(m, read_clip(data, m.name)).max_err_cm <= 1.0
    assert Library.from_bytes(pga_lib).group_sections(0)["m"]  # the shared pose model


def test_append_codes_new_clips_against_the_stored_model_and_keeps_the_others_bytes(runs, pga_lib) -> None:
    from mocapz.libraries import append_library

    old = Library.from_bytes(pga_lib)
    other = runs[2]  # subject 2: a new skeleton, same layout: coded against group 0's model
    again = runs[0].slice(10, 120)
    again.name = "09_06_part"
    data = append_library(pga_lib, [other, again], max_error="1cm")
    new = Library.from_bytes(data)
    for key, payload in old.sections.items():
        assert new.sections[key] == payload  # every clip, group and skeleton already there: same bytes
    assert [c["group"] for c in new.index["clips"]] == [0, 0, 0, 0] and len(new.index["groups"]) == 1
    assert [c["skeleton"] for c in new.index["clips"]] == [0, 0, 1, 0]
    for m in (other, again):
        assert evaluate(m, read_clip(data, m.name)).max_err_cm <= 1.0
    with pytest.raises(OptionError):
        append_library(pga_lib, [], max_error="1cm")


def test_extract_reads_one_clip_alone_and_the_checksum_finds_a_damaged_clip(runs, pga_lib, tmp_path) -> None:
    from mocapz.libraries import extract_clip, list_clips, verify_library

    path = tmp_path / "lib.mczdb"
    lib = Library.from_bytes(pga_lib)
    whole = read_clip(pga_lib, "09_01")
    part = extract_clip(_write(path, pga_lib), "09_01", frames=slice(20, 60))
    np.testing.assert_array_equal(part.channels, whole.channels[20:60])
    assert [c["name"] for c in list_clips(pga_lib)] == ["09_06", "09_01"]
    assert verify_library(pga_lib, decode=True)["ok"]
    # damage one byte of clip 0's residual: clip 1 still comes out, clip 0 is refused, verify names it
    res = lib.sections["c0.c.res"]
    at = pga_lib.index(res) + len(res) // 2
    bad = pga_lib[:at] + bytes([pga_lib[at] ^ 0x40]) + pga_lib[at + 1 :]
    _write(path, bad)
    np.testing.assert_array_equal(extract_clip(path, "09_01").channels, whole.channels)
    with pytest.raises(FormatError, match="'09_06' is damaged"):
        extract_clip(path, "09_06")
    report = verify_library(bad)
    assert not report["ok"] and not report["file_checksum"]
    assert [(c["name"], c["damaged"]) for c in report["clips"]] == [("09_06", ["clip"]), ("09_01", [])]
    with pytest.raises(FormatError, match="checksum"):
        read_clip(bad, "09_01")  # the bytes API checks the whole file


def _write(path, data: bytes):
    path.write_bytes(data)
    return path


def test_library_bytes_are_deterministic_and_a_version_1_library_still_reads(runs) -> None:
    import json

    import zstandard

    from mocapz.codecs.baselines.quant import ENCODE
    from mocapz.format.container import seal, write_sections
    from mocapz.format.entropy import write_uvarint
    from mocapz.format.layout import encode_layout

    a = compress_library(runs[:2], codec="quant", max_error="1cm")
    assert a == compress_library(runs[:2], codec="quant", max_error="1cm")
    m = runs[1]
    index = {"codec": "quant", "codec_version": 3, "groups": [{"kind": "skeleton"}],
             "clips": [{"name": m.name, "group": 0, "frames": m.n_frames, "frame_rate": m.frame_rate,
                        "kind": m.kind, "format": "bvh", "raw_bytes": m.raw_bytes}], "settings": {}}
    sections = {"c0.L": encode_layout(m), **{f"c0.{k}": v for k, v in ENCODE(m, max_error=1.0 / 5.6444).items()}}
    head = zstandard.ZstdCompressor().compress(json.dumps(index).encode())
    v1 = seal(b"MCZL\x1a\x01" + write_uvarint(len(head)) + head + write_sections(sections))
    assert evaluate(m, read_clip(v1, m.name)).max_err_cm <= 1.0
    with pytest.raises(FormatError, match="version 1"):
        from mocapz.libraries import append_library

        append_library(v1, [runs[0]])


def test_cli_library_modes_append_extract_verify(tmp_path) -> None:
    runner = CliRunner()
    lib = tmp_path / "q.mczdb"
    first, second = (str(data_path(p)) for p in SAME_SKELETON)
    res = runner.invoke(cli, ["compress-db", first, "-o", str(lib), "--codec", "quant", "--max-error", "1cm"])
    assert res.exit_code == 0, res.output
    before = lib.read_bytes()
    two = tmp_path / "two.mczdb"
    res = runner.invoke(cli, ["compress-db", first, "-o", str(two), "--codec", "QUANT", "--max-error", "1cm",
                              "-j", "2"])
    assert res.exit_code == 0 and two.read_bytes() == before  # the same bytes whatever --jobs
    res = runner.invoke(cli, ["compress-db", second, "-o", str(lib), "--append", "--max-error", "1cm", "--json"])
    assert res.exit_code == 0, res.output
    assert describe_library(lib)["clips"] == ["09_06", "09_01"] and len(lib.read_bytes()) > len(before)
    res = runner.invoke(cli, ["compress-db", second, "-o", str(lib), "--append", "--codec", "pga"])
    assert isinstance(res.exception, OptionError) and "quant library" in str(res.exception)  # nothing written
    out = tmp_path / "part.bvh"
    res = runner.invoke(cli, ["decompress", str(lib), "--clip", "09_01", "--frames", "10:50", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert load(out).n_frames == 40
    res = runner.invoke(cli, ["verify", str(lib), "--decode", "--json"])
    assert res.exit_code == 0 and '"ok": true' in res.output
    res = runner.invoke(cli, ["compress-db", first, "-o", str(tmp_path / "x.mczdb"), "--codec", "lossless"])
    assert isinstance(res.exception, OptionError) and "no library mode" in str(res.exception)


def test_a_failed_append_leaves_the_library_as_it_was(tmp_path, monkeypatch) -> None:
    """The new library is written to a temporary file renamed into place: a failure midway (here the encoder
    of the new clip) leaves the old file byte for byte; a truncated library is an error naming the file."""
    import mocapz.libraries as libraries
    from mocapz.codecs.library import LibraryMode

    runner = CliRunner()
    lib = tmp_path / "q.mczdb"
    first, second = (str(data_path(p)) for p in SAME_SKELETON)
    assert runner.invoke(cli, ["compress-db", first, "-o", str(lib), "--codec", "quant"]).exit_code == 0
    before = lib.read_bytes()
    real = libraries.library_mode

    def broken(codec: str) -> LibraryMode:
        mode = real(codec)

        def fail(*args: object) -> list:
            raise MocapzError("encoder failed midway")

        return LibraryMode(mode.codec, mode.version, mode.encode_group, fail, mode.decode, mode.group_key)

    monkeypatch.setattr(libraries, "library_mode", broken)
    res = runner.invoke(cli, ["compress-db", second, "-o", str(lib), "--append"])
    assert res.exit_code != 0 and "midway" in str(res.exception)
    assert lib.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["q.mczdb"]
    (tmp_path / "cut.mczdb").write_bytes(before[: len(before) // 2])
    with pytest.raises(FormatError, match="cut.mczdb"):
        describe_library(tmp_path / "cut.mczdb")


def test_a_large_pga_group_is_fitted_on_a_sample_and_analysed_again_with_the_same_bytes(runs, pga_lib,
                                                                                         monkeypatch) -> None:
    """Memory bounded whatever the library's length: with no analysed clip kept from the model's fit to the
    coding (every clip analysed again) the library has the very bytes of the default; with the model fitted on
    every 4th frame of the group, a different model and every clip still within its target."""
    from mocapz.codecs.pga import library as pga_library

    monkeypatch.setattr(pga_library, "HOLD_FRAMES", 0)
    assert compress_library(runs[:2], codec="pga", max_error="1cm") == pga_lib
    total = sum(m.n_frames for m in runs[:2])
    monkeypatch.setattr(pga_library, "FIT_FRAMES", total // 4)
    sampled = compress_library(runs[:2], codec="pga", max_error="1cm")
    lib, full = Library.from_bytes(sampled), Library.from_bytes(pga_lib)
    assert lib.group_sections(0)["m"] != full.group_sections(0)["m"]
    for m in runs[:2]:
        assert evaluate(m, read_clip(sampled, m.name)).max_err_cm <= 1.0


@pytest.mark.parametrize("codec", ["pga", "patterns", "quant"])
def test_library_progress_reports_every_clip_once(runs, codec) -> None:
    from mocapz.libraries import append_library

    seen: list[int] = []
    data = compress_library(runs[:2], codec=codec, progress=seen.append, max_error="2cm")
    assert seen == [m.n_frames for m in runs[:2]]
    seen.clear()
    append_library(data, [runs[2]], progress=seen.append, max_error="2cm")
    assert seen == [runs[2].n_frames]


def test_compress_db_and_verify_messages(tmp_path) -> None:
    """-q: nothing on stderr but errors; verify names a damaged clip on one line (every clip only with -v) and
    exits 1."""
    runner = CliRunner()
    lib = tmp_path / "q.mczdb"
    first, second = (str(data_path(p)) for p in SAME_SKELETON)
    res = runner.invoke(cli, ["compress-db", first, second, "-o", str(lib), "--codec", "quant", "-q"])
    assert res.exit_code == 0 and res.stderr == "" and res.stdout == ""
    res = runner.invoke(cli, ["compress-db", first, "-o", str(lib), "--codec", "quant", "-f"])
    assert res.exit_code == 0 and res.stderr.startswith("1 clip -> ")
    res = runner.invoke(cli, ["compress-db", first, second, "-o", str(lib), "--codec", "quant", "-f"])
    good = lib.read_bytes()
    lib2 = Library.from_bytes(good)
    name, payload = next((k, v) for k, v in lib2.sections.items() if k.startswith("c1.") and len(v) > 8)
    damaged = bytearray(good)
    at = good.index(payload) + len(payload) // 2
    damaged[at] ^= 0xFF
    lib.write_bytes(bytes(damaged))
    res = runner.invoke(cli, ["verify", str(lib)])
    lines = res.stderr.strip().splitlines()
    assert res.exit_code == 1 and len(lines) == 2 and lines[0].startswith("09_01: DAMAGED"), res.stderr
    res = runner.invoke(cli, ["verify", str(lib), "-v"])
    assert res.exit_code == 1 and res.stderr.splitlines()[0] == "09_06: ok"
    res = runner.invoke(cli, ["verify", str(lib), "-q"])
    assert res.exit_code == 1 and res.stderr.splitlines() == lines[:1]


def test_a_library_of_more_than_ten_skeletons_verifies(runs) -> None:
    """Skeleton 1's checksum covers section s1 alone, not s10, s11...: a library of 12 skeletons (one clip with
    its bones scaled 12 ways) verifies whole, and a damaged s1 is found on its clip only."""
    from dataclasses import replace

    from mocapz.libraries import verify_library

    short = runs[0].slice(0, 40)
    clips = []
    for i in range(12):
        sk = short.skeleton.copy()
        sk.offsets = sk.offsets * (1.0 + 0.01 * i)
        clips.append(replace(short, skeleton=sk, name=f"scaled_{i}"))
    data = compress_library(clips, codec="quant", max_error="2cm")
    lib = Library.from_bytes(data)
    assert len(lib.index["skeletons"]) == 12
    report = verify_library(data, decode=True)
    assert report["ok"], [c for c in report["clips"] if not c["ok"]]
    payload = lib.sections["s1"]
    at = data.index(payload) + len(payload) // 2
    bad = bytearray(data)
    bad[at] ^= 0x55
    report = verify_library(bytes(bad))
    assert [c["name"] for c in report["clips"] if not c["ok"]] == ["scaled_1"]
    assert report["clips"][1]["damaged"] == ["skeleton"]


def test_compress_db_leaves_out_a_clip_its_codec_does_not_take(tmp_path) -> None:
    """A marker file in the inputs of a pga library is one error line and left out (exit code 1); the skeletal
    clips are coded."""
    lib = tmp_path / "p.mczdb"
    bvh, trc = str(data_path(SAME_SKELETON[0])), str(data_path("other/markers/btkdata/Gait.trc"))
    res = CliRunner().invoke(cli, ["compress-db", trc, bvh, "-o", str(lib), "--codec", "pga", "--max-error", "2cm"])
    assert res.exit_code == 1, res.output
    assert res.stderr.splitlines()[0] == f"mocapz: error: {trc}: the pga codec does not take markers data (it " \
                                         "takes skeleton data)"
    assert describe_library(lib)["clips"] == ["09_06"]


def test_library_coded_on_two_workers_has_the_same_bytes(runs, pga_lib) -> None:
    """Every clip is coded on its own (after its group's shared model or databases): the bytes do not depend on
    where, for every library mode, compressed or appended."""
    from mocapz.libraries import append_library

    assert compress_library(runs[:2], codec="pga", max_error="1cm", jobs=2) == pga_lib
    assert append_library(pga_lib, [runs[2]], max_error="1cm", jobs=2) == append_library(pga_lib, [runs[2]],
                                                                                       max_error="1cm")
    short = [m.slice(0, 120) for m in runs]
    for codec in ("quant", "patterns"):
        assert compress_library(short, codec=codec, max_error="2cm", jobs=2) == \
            compress_library(short, codec=codec, max_error="2cm"), codec


@pytest.mark.parametrize("where, value", [
    ("clip", True), ("clip.name", None), ("clip.group", 7), ("clip.group", "0"), ("clip.skeleton", 5),
    ("clip.frames", -1), ("clip.frame_rate", 0), ("clip.crc", None), ("group", []), ("skeletons", {}),
    ("skeleton", []), ("codec", 3), ("clip.name", "09_06")])
def test_a_hostile_library_index_is_one_error_naming_the_file(runs, tmp_path, where, value) -> None:
    """An index written with a valid checksum but a clip that is not an object, a group or skeleton number past
    the lists, a name twice...: every reader (API and CLI) raises FormatError naming the file, no KeyError or
    TypeError (the whole file's checksum is recomputed: a faulty writer, not a flipped bit)."""
    import json
    import struct
    import zlib

    import zstandard

    from mocapz.format.container import write_sections
    from mocapz.format.entropy import write_uvarint
    from mocapz.format.library import FORMAT_VERSION, MAGIC
    from mocapz.libraries import extract_clip, verify_library

    good = Library.from_bytes(compress_library([m.slice(0, 30) for m in runs[:2]], codec="quant", max_error="2cm"))
    index = json.loads(json.dumps(good.index))
    kind, _, field = where.partition(".")
    if kind == "clip":
        if field:
            index["clips"][1][field] = value
        else:
            index["clips"][1] = value
    elif kind == "group":
        index["groups"][0] = value
    elif kind == "skeleton":
        index["skeletons"][0] = value
    else:
        index[kind] = value
    head = zstandard.ZstdCompressor().compress(json.dumps(index).encode())
    body = MAGIC + bytes([FORMAT_VERSION]) + write_uvarint(len(head)) + head + write_sections(good.sections)
    path = tmp_path / "hostile.mczdb"
    path.write_bytes(body + struct.pack("<I", zlib.crc32(body) & 0xFFFFFFFF))
    for read in (lambda: read_clip(path.read_bytes(), "09_01", path), lambda: extract_clip(path, "09_01"),
                 lambda: verify_library(path.read_bytes(), path), lambda: describe_library(path)):
        with pytest.raises(FormatError, match="hostile.mczdb.*bad index"):
            read()
    for args in (["info", str(path)], ["verify", str(path)], ["decompress", str(path), "--clip", "09_01", "-o",
                                                                str(tmp_path / "o.bvh")]):
        res = CliRunner().invoke(cli, args)
        assert isinstance(res.exception, FormatError) and "bad index" in str(res.exception), (args, res.exception)
