"""Everything a C3D file holds survives every codec (issue 10): parameters (every group, unknown ones
too), analog channels, events, residuals and camera masks, descriptions, units; Plug-in-Gait model
outputs are tracks of their own, not markers; integer C3D comes back as the same integers; every
readable sample file comes back byte for byte through the lossless codec."""

from __future__ import annotations

import hashlib
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.format.layout import decode_header, encode_layout
from mocapz.model.c3d_extras import C3DExtras, float_values, float_words

SAMPLES = "other/markers/btkdata/c3d_samples"
PIG = f"{SAMPLES}/PiG_Motion-FlatFoot-Full.c3d"
ANALOGS = "other/markers/pyomeca/markers_analogs.c3d"
EB015 = [f"{SAMPLES}/Eb015{s}.c3d" for s in ("pi", "pr", "si", "sr", "vi", "vr")]
READABLE = EB015 + [f"{SAMPLES}/FP1.C3D", f"{SAMPLES}/Dance.c3d", PIG, ANALOGS, "cmu/c3d/01_01.c3d"]


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _through(rel: str, codec: str, tmp_path: Path) -> tuple[mocapz.MarkerMotion, Path]:
    """The file compressed with ``codec``, decompressed and written as C3D; no warning may be raised."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = mocapz.decompress(mocapz.compress(data_path(rel), codec=codec))
    out = tmp_path / f"{Path(rel).stem}.{codec}.c3d"
    mocapz.save(back, out)
    return back, out


@pytest.mark.parametrize("rel", READABLE)
def test_lossless_gives_the_same_file(rel: str, tmp_path: Path) -> None:
    """Every readable sample: lossless compress + decompress writes the source file's bytes."""
    back, out = _through(rel, "lossless", tmp_path)
    assert _sha(out) == _sha(data_path(rel))
    src = mocapz.load(data_path(rel))
    np.testing.assert_array_equal(back.positions, src.positions)
    assert back.quantum == src.quantum


def _params(c3d: object) -> dict[tuple[str, str], object]:
    out = {}
    for group, params in c3d["parameters"].items():  # type: ignore[index]
        for name, p in params.items():
            if isinstance(p, dict) and "value" in p:
                v = p["value"]
                out[(group, name)] = [str(x) for x in v] if isinstance(v, list) else np.asarray(v).tolist()
    return out


@pytest.mark.parametrize("codec", ["lossless", "patterns"])
@pytest.mark.parametrize("rel", [ANALOGS, PIG])
def test_parameters_analogs_events_residuals_survive(rel: str, codec: str, tmp_path: Path) -> None:
    """Read back with ezc3d: every parameter of every group (EVENT, SUBJECTS, TRIAL, PROCESSING, unknown
    ones), the analogs and the residuals are the source's, whatever codec coded the markers."""
    import ezc3d

    src = ezc3d.c3d(str(data_path(rel)))
    _, out = _through(rel, codec, tmp_path)
    got = ezc3d.c3d(str(out))
    assert _params(got) == _params(src)
    assert {"EVENT", "SUBJECTS", "TRIAL"} <= set(src["parameters"])
    assert src["data"]["analogs"].shape[1] == 38
    np.testing.assert_array_equal(got["data"]["analogs"], src["data"]["analogs"])
    np.testing.assert_array_equal(got["data"]["meta_points"]["residuals"], src["data"]["meta_points"]["residuals"])
    np.testing.assert_array_equal(got["data"]["meta_points"]["camera_masks"],
                                  src["data"]["meta_points"]["camera_masks"])
    if codec == "lossless":
        assert _sha(out) == _sha(data_path(rel))
    else:  # the markers moved, nothing else did: same size, same bytes outside the points
        assert out.stat().st_size == data_path(rel).stat().st_size


def test_model_outputs_are_tracks() -> None:
    """Plug-in-Gait: the 80 points named in POINT:ANGLES/FORCES/MOMENTS/POWERS are tracks with their units,
    not markers; their values are the file's."""
    import ezc3d

    m = mocapz.load(data_path(PIG))
    extras = m.metadata["c3d"]
    assert isinstance(extras, C3DExtras)
    assert m.n_markers == 113 and len(extras.track_labels) == 80
    assert not set(extras.track_labels) & set(m.labels)
    assert "LKneeAngles" in extras.track_labels and "LASI" in m.labels
    assert set(extras.track_kinds) == {"ANGLES", "FORCES", "MOMENTS", "POWERS"}
    units = dict(zip(extras.track_kinds, extras.track_units, strict=True))
    assert units == {"ANGLES": "deg", "FORCES": "N", "MOMENTS": "Nmm", "POWERS": "W"}
    points = ezc3d.c3d(str(data_path(PIG)))["data"]["points"][:3].transpose(2, 1, 0)
    np.testing.assert_array_equal(extras.track_values(), points[:, extras.track_index])
    np.testing.assert_array_equal(m.positions, points[:, extras.marker_index])


def test_integer_c3d_is_the_same_integers() -> None:
    """Integer storage (PC, DEC, SGI): positions are int16 * |scale| exactly, ``quantum`` is |scale|, the six
    storages give the same markers to the scale, and the lossless codec gives them back exactly."""
    motions = [mocapz.load(data_path(rel)) for rel in EB015]
    pi = motions[0]
    q = pi.quantum
    assert q == pytest.approx(1 / 12, rel=1e-6)
    present = ~pi.missing
    ints = pi.positions[present] / q
    np.testing.assert_array_equal(ints, np.round(ints))
    for rel, m in zip(EB015, motions, strict=True):
        assert (m.quantum is None) == rel.endswith("r.c3d"), rel
        np.testing.assert_allclose(m.positions[present], pi.positions[present], atol=q * 1e-3, err_msg=rel)
        back = mocapz.decompress(mocapz.compress(m, codec="lossless"))
        np.testing.assert_array_equal(back.positions, m.positions)


def test_sliced_clip_writes_a_consistent_file(tmp_path: Path) -> None:
    """Frames 100:200 of the analog trial: the header, POINT:FRAMES and TRIAL:ACTUAL_START_FIELD / END_FIELD
    say those frames, the analogs are those frames' samples, and every other parameter is the source's."""
    import ezc3d

    m = mocapz.load(data_path(ANALOGS))
    back = mocapz.decompress(mocapz.compress(m.slice(100, 200), codec="quant"))
    mocapz.save(back, tmp_path / "cut.c3d")
    src, got = ezc3d.c3d(str(data_path(ANALOGS))), ezc3d.c3d(str(tmp_path / "cut.c3d"))
    assert got["data"]["points"].shape == (4, 51, 100)
    assert got["header"]["points"]["first_frame"] == src["header"]["points"]["first_frame"] + 100
    np.testing.assert_array_equal(got["data"]["analogs"], src["data"]["analogs"][:, :, 2000:4000])
    a, b = _params(src), _params(got)
    assert b.pop(("POINT", "FRAMES")) == [100]
    assert a.pop(("TRIAL", "ACTUAL_START_FIELD")) == [1, 0] and b.pop(("TRIAL", "ACTUAL_START_FIELD")) == [101, 0]
    assert a.pop(("TRIAL", "ACTUAL_END_FIELD")) == [580, 0] and b.pop(("TRIAL", "ACTUAL_END_FIELD")) == [200, 0]
    a.pop(("POINT", "FRAMES"))
    assert a == b
    assert (tmp_path / "cut.c3d").stat().st_size % 512 == 0


def test_quantum_in_the_layout() -> None:
    """The layout carries ``quantum`` for integer C3D and omits the key otherwise."""
    m = mocapz.load(data_path(EB015[0]))
    assert decode_header(encode_layout(m)).quantum == m.quantum
    f = mocapz.load(data_path(EB015[1]))
    assert f.quantum is None and decode_header(encode_layout(f)).quantum is None
    assert b"quantum" not in encode_layout(f)


@pytest.mark.parametrize("processor", [84, 85, 86])
def test_float_words_invert_float_values(processor: int) -> None:
    values = np.array([0.0, -0.0, 1.5, -2.25, 1e-30, 3e30, 1234.5678, -7.0], dtype=np.float32).astype(np.float64)
    words = float_words(values, processor)
    np.testing.assert_array_equal(float_values(words, processor), values)


@pytest.mark.slow
def test_cli_patterns_on_pig_has_no_warnings(tmp_path: Path) -> None:
    """The patterns codec on the Plug-in-Gait trial: model outputs are not markers, and no RuntimeWarning
    (All-NaN slice...) reaches the terminal."""
    out = tmp_path / "pig.mcz"
    run = subprocess.run([sys.executable, "-W", "error::RuntimeWarning", "-m", "mocapz", "compress",
                          str(data_path(PIG)), "-o", str(out), "--codec", "patterns"],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "Warning" not in run.stderr
    back = mocapz.decompress(out.read_bytes())
    assert back.n_markers == 113 and len(back.metadata["c3d"].track_labels) == 80


def test_library_clips_keep_their_extras() -> None:
    """compress-db libraries carry each C3D clip's extras beside its pattern streams."""
    from mocapz.libraries import compress_library, read_clip

    clip = mocapz.load(data_path(EB015[1])).slice(0, 150)
    back = read_clip(compress_library([clip]), clip.name)
    got, want = back.metadata["c3d"], clip.metadata["c3d"]
    np.testing.assert_array_equal(got.analog_words, want.analog_words)
    np.testing.assert_array_equal(got.residual_words, want.residual_words)
    assert got.params == want.params and got.header == want.header


def test_viewer_and_info_see_markers_and_tracks() -> None:
    """The viewer draws the 113 markers of the Plug-in-Gait trial only; ``mocapz info`` names its tracks and
    analog channels."""
    from mocapz.cli.describe import describe
    from mocapz.viewer.data import prepare_view

    m = mocapz.load(data_path(PIG))
    view = prepare_view(m, budget=None)
    assert view.names == m.labels and view.original.shape[1] == 113
    d = describe(data_path(PIG))
    assert d["markers"] == 113 and d["analog_channels"] == 38 and d["c3d_storage"] == "Intel float32"
    assert d["tracks"] == "26 ANGLES (deg), 16 POWERS (W), 20 FORCES (N), 18 MOMENTS (Nmm)"


@pytest.mark.parametrize("bad", [0, -0.1, float("nan"), float("inf"), "0.1", [0.1], True])
def test_layout_refuses_a_bad_quantum(bad: object) -> None:
    from mocapz.errors import FormatError
    from mocapz.format.layout import layout_dict
    from mocapz.format.layout_check import check_layout

    d = layout_dict(mocapz.load(data_path(EB015[0])).slice(0, 5))
    check_layout(d)
    d["quantum"] = bad
    with pytest.raises(FormatError, match="quantum"):
        check_layout(d)


def test_integer_file_with_scale_zero(tmp_path: Path) -> None:
    """POINT:SCALE 0 in an integer file: positions 0, no quantum, no warning, the file back byte for byte."""
    import struct

    raw = bytearray(data_path(EB015[0]).read_bytes())
    at = raw.find(struct.pack("<f", np.float32(1 / 12)), 512)  # POINT:SCALE's value
    assert at > 512
    raw[at:at + 4] = struct.pack("<f", 0.0)
    (tmp_path / "zero.c3d").write_bytes(bytes(raw))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = mocapz.load(tmp_path / "zero.c3d")
        back = mocapz.decompress(mocapz.compress(m))
        mocapz.save(back, tmp_path / "out.c3d")
    assert m.quantum is None and np.nanmax(np.abs(m.positions)) == 0
    assert (tmp_path / "out.c3d").read_bytes() == bytes(raw)


def test_c3d_sections_as_documented() -> None:
    """docs/format.md 5.1, by hand: the c3d.file section holds the JSON, the header and the parameter section;
    c3d.fix starts with the packed mask of the missing samples."""
    import json
    import lzma

    import zstandard

    from mocapz.format.container import Container
    from mocapz.format.entropy import read_uvarint

    path = data_path(ANALOGS)
    raw = path.read_bytes()
    box = Container.from_bytes(mocapz.compress(path, codec="lossless", block=0))  # one block (see test_c3d_blocks)
    assert [k for k in box.sections if k.startswith("c3d.")] == ["c3d.file", "c3d.res", "c3d.trk", "c3d.ana", "c3d.fix"]
    file = box.sections["c3d.file"]
    assert file[0] == 1
    static = lzma.decompress(file[1:], format=lzma.FORMAT_XZ)
    parts, pos = [], 0
    for _ in range(4):
        n, pos = read_uvarint(static, pos)
        parts.append(static[pos:pos + n])
        pos += n
    info = json.loads(parts[0])
    assert info["processor"] == 84 and info["float"] is True and info["channels"] == 38 and info["samples"] == 20
    assert info["markers"] == list(range(51)) and info["tracks"] == []
    assert parts[1] == raw[:512] and parts[2] == b"" and parts[3] == raw[512:28 * 512]
    assert static[pos:] == b"\x01\x00"  # the data ends the file: no trailing bytes
    fix = box.sections["c3d.fix"]
    n, pos = read_uvarint(fix, 0)
    mask = np.unpackbits(np.frombuffer(zstandard.ZstdDecompressor().decompress(fix[pos:pos + n]), np.uint8))
    m = mocapz.load(path)
    np.testing.assert_array_equal(mask[:m.missing.size].astype(bool), m.missing.ravel())


def test_lossy_decode_drops_the_quantum() -> None:
    """Decoded values that are no longer multiples of the scale do not claim a quantum (lossless ones do)."""
    m = mocapz.load(data_path(EB015[4])).slice(0, 100)
    assert m.quantum is not None
    assert mocapz.decompress(mocapz.compress(m, codec="lossless")).quantum == m.quantum
    assert mocapz.decompress(mocapz.compress(m, codec="quant")).quantum is None
