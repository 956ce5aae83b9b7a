"""The shared C3D files (MANIFEST: other/markers/btkdata/c3d_samples/, cmu/c3d, other/markers/pyomeca):
the reader chosen for each (ezc3d, else the pure-Python c3d package), one trial in six storages gives one
motion, the c3d package's values and parameters agree with mocapz's raw decoder (mocapz.io.c3d_raw) and
with ezc3d, its warnings never reach the user, and bad files give a clean FormatError."""

from __future__ import annotations

import logging
import struct
import subprocess
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA, data_path

from mocapz.errors import FormatError
from mocapz.io.c3d import read_c3d, write_c3d
from mocapz.io.c3d_checks import C3DLayout, check_c3d_file
from mocapz.io.c3d_pure import read_c3d_package
from mocapz.io.c3d_raw import split_c3d
from mocapz.model.motion import MarkerMotion

SAMPLES = "other/markers/btkdata/c3d_samples"
EB015 = {s: f"{SAMPLES}/Eb015{s}.c3d" for s in ("pi", "pr", "si", "sr", "vi", "vr")}  # PC, SGI, DEC x int, real


@dataclass(frozen=True)
class Refused:
    """A file read_c3d refuses with a FormatError whose message contains ``message``."""

    message: str


MIPS = "c3d (ezc3d not given the file: SGI/MIPS storage, which ezc3d does not read)"
#: every shared C3D file: the reader that reads it, or the FormatError it gives
READERS = {
    **{EB015[s]: "ezc3d" for s in ("pi", "pr", "vi", "vr")},
    EB015["si"]: MIPS,
    EB015["sr"]: MIPS,
    f"{SAMPLES}/Dance.c3d": "c3d (ezc3d not given the file: POINT:FRAMES (500) runs past the end of the file, "
                            "the header's 499 frames fill it)",
    f"{SAMPLES}/FP1.C3D": "ezc3d",
    f"{SAMPLES}/PiG_Motion-FlatFoot-Full.c3d": "ezc3d",
    f"{SAMPLES}/Empty.c3d": Refused("file is empty"),
    f"{SAMPLES}/bad_parameter_section.c3d": Refused("corrupt C3D: data start block 12 lies inside"),
    "cmu/c3d/01_01.c3d": "ezc3d",
    "other/markers/pyomeca/markers_analogs.c3d": "ezc3d",
}
READABLE = [rel for rel, r in READERS.items() if isinstance(r, str)]
EZC3D_READS = [rel for rel, r in READERS.items() if r == "ezc3d"]
PACKAGE_READS = [rel for rel in READABLE if rel != "cmu/c3d/01_01.c3d"]  # c3d: "inconsistent analog rate!"


def _load(rel: str) -> MarkerMotion:
    return read_c3d(data_path(rel))


def _package(rel: str) -> tuple[dict, C3DLayout]:
    path = data_path(rel)
    layout = check_c3d_file(path)
    return read_c3d_package(path, layout), layout


def test_every_shared_c3d_file_is_listed() -> None:
    """A C3D file added to the shared data must get a row in READERS."""
    found = {str(p.relative_to(DATA)) for p in DATA.rglob("*") if p.suffix.lower() == ".c3d"}
    assert found == set(READERS)


@pytest.mark.parametrize("rel", sorted(READERS))
def test_reader_chosen(rel: str) -> None:
    """Each file is read by the expected reader (saying why ezc3d did not read it), or refused cleanly;
    no warning may reach the user."""
    want = READERS[rel]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        if isinstance(want, Refused):
            with pytest.raises(FormatError, match=want.message) as err:
                _load(rel)
            assert str(data_path(rel)) in str(err.value)
            return
        m = _load(rel)
    assert m.metadata["c3d_reader"] == want
    assert m.n_frames > 0 and m.n_markers > 0 and m.frame_rate > 0
    assert np.isfinite(m.positions[~m.missing]).all()


@pytest.mark.parametrize("name", ["Empty.c3d", "bad_parameter_section.c3d"])
def test_bad_samples_give_one_line_from_the_cli(name: str) -> None:
    """In a child process (a crash or hang fails the test, not pytest): one error line, exit code 1."""
    path = data_path(f"{SAMPLES}/{name}")
    run = subprocess.run([sys.executable, "-m", "mocapz.cli.main", "info", str(path)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 1, run.stderr
    assert "Traceback" not in run.stderr and run.stderr.count("\n") == 1
    assert str(path) in run.stderr


def test_eb015_storages_give_one_motion() -> None:
    """Six storages of one trial (ezc3d reads PC and DEC, the c3d package SGI): same labels, rate, shape,
    gaps, residuals, analogs; the integer files give ``int * POINT:SCALE`` with the same integers, the
    float files its float32 rounding."""
    eb015 = {s: _load(rel) for s, rel in EB015.items()}
    pi = eb015["pi"]
    assert pi.positions.shape == (450, 26, 3) and pi.frame_rate == 50.0 and pi.units == "mm"
    q = pi.quantum
    assert q == pytest.approx(1 / 12, rel=1e-6)
    for s, m in eb015.items():
        assert m.labels == pi.labels and m.frame_rate == pi.frame_rate and m.units == pi.units, s
        np.testing.assert_array_equal(m.missing, pi.missing, err_msg=s)
        np.testing.assert_array_equal(m.metadata["residuals"], pi.metadata["residuals"], err_msg=s)
        np.testing.assert_array_equal(m.metadata["analogs"], pi.metadata["analogs"], err_msg=s)
        want = pi.positions if s.endswith("i") else pi.positions.astype(np.float32).astype(np.float64)
        np.testing.assert_array_equal(m.positions, want, err_msg=s)
        assert m.metadata["c3d_float"] == s.endswith("r") and (m.quantum is None) == s.endswith("r")
        present = ~m.missing
        np.testing.assert_array_equal(np.round(m.positions[present] / q), np.round(pi.positions[present] / q))
    assert {eb015[s].metadata["c3d_processor"] for s in ("si", "sr")} == {86}


@pytest.mark.parametrize("rel", PACKAGE_READS)
def test_c3d_package_agrees_with_the_raw_decoder(rel: str) -> None:
    """On every file the c3d package reads: its points are the file's words (float storage exactly,
    integer storage ``int16 * scale`` rounded to float32), its gaps the raw decoder's, every parameter
    the checks decoded has the same values (DEC float zeros included), its analogs are
    ``(word - OFFSET) * SCALE * GEN_SCALE`` of the stored words."""
    ours, layout = _package(rel)
    labels, positions, extras = split_c3d(data_path(rel), layout)
    points = ours["data"]["points"][:3].transpose(2, 1, 0)[:, extras.marker_index]
    assert points.shape == positions.shape
    np.testing.assert_array_equal(np.isnan(points), np.isnan(positions))
    present = ~np.isnan(positions)
    if layout.header.is_float:
        np.testing.assert_array_equal(points[present], positions[present])
    else:
        scales = np.broadcast_to(extras.scales[extras.marker_index][None, :, None], positions.shape)[present]
        np.testing.assert_array_equal(np.round(points[present] / scales), np.round(positions[present] / scales))
        np.testing.assert_allclose(points[present], positions[present], rtol=2 ** -23, atol=0)
    names = [s.strip() for s in ours["parameters"]["POINT"]["LABELS"]["value"]] + [""] * layout.points
    assert [names[i] or f"*{i + 1}" for i in extras.marker_index] == labels
    for (group, name), param in layout.params.items():
        got = ours["parameters"][group][name]["value"]
        if param.kind == -1:
            assert got == param.strings(), (group, name)
        else:
            np.testing.assert_array_equal(got, param.numbers(layout.header.processor), err_msg=f"{group}:{name}")
    analogs = ours["data"]["analogs"][0]
    assert analogs.shape == (layout.channels, layout.frames * layout.samples)
    if layout.channels:
        n = layout.channels
        number = lambda key: layout.params[("ANALOG", key)].numbers(layout.header.processor)  # noqa: E731
        want = (extras.analog_values().T - np.trunc(number("OFFSET")[:n, None])) * number("SCALE")[:n, None] \
            * number("GEN_SCALE")[0]
        np.testing.assert_allclose(analogs, want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("rel", [rel for rel in EZC3D_READS if rel in PACKAGE_READS])
def test_c3d_package_gives_ezc3d_values(rel: str) -> None:
    """Where both read a file: the same analogs, bit for bit, the same gaps and first frame, and points to
    float32 rounding."""
    import ezc3d

    ours, _ = _package(rel)
    theirs = ezc3d.c3d(str(data_path(rel)), extract_forceplat_data=False)
    np.testing.assert_array_equal(ours["data"]["analogs"], np.asarray(theirs["data"]["analogs"]))
    pts = np.asarray(theirs["data"]["points"])
    np.testing.assert_array_equal(np.isnan(ours["data"]["points"]), np.isnan(pts))
    np.testing.assert_allclose(ours["data"]["points"], pts, rtol=2 ** -23, atol=0)
    assert ours["header"]["points"]["first_frame"] == theirs["header"]["points"]["first_frame"]
    assert ours["header"]["points"]["last_frame"] == theirs["header"]["points"]["last_frame"]


def test_c3d_package_warnings_never_reach_the_user(caplog: pytest.LogCaptureFixture) -> None:
    """The c3d package warns on Dance.c3d (data start, missing descriptions, EOF); read_c3d shows none."""
    import c3d

    path = data_path(f"{SAMPLES}/Dance.c3d")
    with pytest.warns(UserWarning), path.open("rb") as fh:
        list(c3d.Reader(fh).read_frames())
    caplog.set_level(logging.DEBUG)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_c3d(path)
    assert not caplog.records


def test_dance_is_recovered() -> None:
    """Dance.c3d (PhoeniX; POINT:DATA_START 0, empty descriptions, a float ANALOG:OFFSET, POINT:FRAMES 500
    for 499 frames, an ANALOG group past the parameter blocks it declares): ezc3d refuses it, the c3d
    package reads the 499 frames the file holds, with the ANALOG group (GEN_SCALE -1: analogs = -words)."""
    m = _load(f"{SAMPLES}/Dance.c3d")
    assert m.positions.shape == (499, 40, 3) and m.units == "mm"
    assert m.frame_rate == pytest.approx(65.0533, abs=1e-4)
    assert m.labels[:2] == ["Channel101", "Channel102"] and m.metadata["point_descriptions"] == [""] * 40
    assert m.metadata["c3d_reader"].startswith("c3d (")
    present = m.positions[~m.missing]
    assert present.size and np.isfinite(present).all() and np.abs(present).max() < 3000  # mm, a room
    step = np.linalg.norm(np.diff(m.positions, axis=0), axis=2)
    assert np.nanmedian(step) < 20  # mm per frame at 65 Hz: a body moving, not garbage
    assert m.metadata["analogs"].shape == (8, 499) and np.isfinite(m.metadata["analogs"]).all()
    np.testing.assert_array_equal(m.metadata["analogs"], -m.metadata["c3d"].analog_values().T)
    assert m.metadata["analog_labels"] == [f"Channel{i}" for i in range(1, 9)]
    assert m.metadata["analog_units"] == ["V"] * 8


def test_dance_with_ezc3d_allowed_is_refused_by_ezc3d(monkeypatch: pytest.MonkeyPatch) -> None:
    """Were ezc3d given Dance.c3d, it would refuse it (the float OFFSET) and the c3d package would read it."""
    import dataclasses

    import mocapz.io.c3d as c3d_module

    real = c3d_module.check_c3d_file
    monkeypatch.setattr(c3d_module, "check_c3d_file", lambda p: dataclasses.replace(real(p), ezc3d_unsafe=""))
    m = _load(f"{SAMPLES}/Dance.c3d")
    assert m.metadata["c3d_reader"] == "c3d (ezc3d: OFFSET parameter is not an INT)"
    assert m.positions.shape == (499, 40, 3)


def test_fp1_parameter_section_longer_than_declared() -> None:
    """FP1.C3D declares 3 parameter blocks and fills 5 (its ANALOG:UNITS crosses block 4): ezc3d reads it,
    and so does the c3d package given the blocks before the data."""
    m = _load(f"{SAMPLES}/FP1.C3D")
    assert m.positions.shape == (480, 8, 3) and m.frame_rate == 60.0 and m.metadata["c3d_reader"] == "ezc3d"
    assert m.metadata["analogs"].shape == (12, 4800) and m.metadata["analog_rate"] == 600.0
    ours, _ = _package(f"{SAMPLES}/FP1.C3D")
    np.testing.assert_array_equal(ours["data"]["analogs"][0], m.metadata["analogs"])


# ------------------------------------------------------------------------------------- synthetic files
def _seed(tmp_path: Path) -> tuple[MarkerMotion, bytes]:
    pos = np.random.default_rng(3).normal(0.0, 400.0, (7, 3, 3))
    pos[2, 1] = np.nan
    m = MarkerMotion(["A", "B", "C"], pos, 100.0, "mm", name="seed")
    write_c3d(m, tmp_path / "seed.c3d")
    return read_c3d(tmp_path / "seed.c3d"), (tmp_path / "seed.c3d").read_bytes()


def _same(a: MarkerMotion, b: MarkerMotion) -> None:
    assert a.labels == b.labels and a.frame_rate == b.frame_rate
    np.testing.assert_array_equal(a.positions, b.positions)


def test_declared_parameter_blocks_are_a_hint(tmp_path: Path) -> None:
    """Records may run past the declared block count, up to the data start (as in FP1.C3D)."""
    seed, data = _seed(tmp_path)
    start = (data[0] - 1) * 512
    data_start = struct.unpack("<H", data[16:18])[0]
    assert data_start - data[0] > 1  # the seed's parameters fill more than one block
    b = bytearray(data)
    b[start + 2] = 1
    (tmp_path / "short.c3d").write_bytes(bytes(b))
    _same(seed, read_c3d(tmp_path / "short.c3d"))


def test_point_frames_past_the_end(tmp_path: Path) -> None:
    """POINT:FRAMES past the end of the file while the header's count fills it (as in Dance.c3d): the
    header's frames are read, by the c3d package; a file cut short of the header's count is still refused.
    (Frames that fit in the padding of the last block are data as far as the file can tell.)"""
    seed, data = _seed(tmp_path)
    at = data.index(b"FRAMES", (data[0] - 1) * 512) + 6 + 2 + 2  # name, offset, type, dimension count
    assert struct.unpack("<h", data[at:at + 2])[0] == 7
    b = bytearray(data)
    b[at:at + 2] = struct.pack("<h", 30)  # 23 frames of 48 bytes more: past the 512-byte padding
    (tmp_path / "frames.c3d").write_bytes(bytes(b))
    m = read_c3d(tmp_path / "frames.c3d")
    _same(seed, m)
    assert m.metadata["c3d_reader"].startswith("c3d (ezc3d not given the file: POINT:FRAMES (30) runs past")
    end = (struct.unpack("<H", data[16:18])[0] - 1) * 512 + 7 * 3 * 16  # the 7 frames of 3 float points
    (tmp_path / "cut.c3d").write_bytes(bytes(b[:end - 16]))
    with pytest.raises(FormatError, match="truncated"):
        read_c3d(tmp_path / "cut.c3d")


def test_ezc3d_refusal_falls_back(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A file whose structure passes the checks but that ezc3d refuses is read by the c3d package; when
    that fails too, the FormatError names the file and both reasons."""
    import c3d
    import ezc3d

    seed, _ = _seed(tmp_path)

    def refuse(*_: object, **__: object) -> None:
        raise RuntimeError("OFFSET parameter is not an INT")

    monkeypatch.setattr(ezc3d, "c3d", refuse)
    m = read_c3d(tmp_path / "seed.c3d")
    _same(seed, m)
    assert m.metadata["c3d_reader"] == "c3d (ezc3d: OFFSET parameter is not an INT)"

    def fail(*_: object) -> None:
        raise AssertionError("inconsistent scale factor! -1.0 header != -0.5 POINT:SCALE")

    monkeypatch.setattr(c3d, "Reader", fail)
    with pytest.raises(FormatError, match=r"seed\.c3d: not a readable C3D file \(ezc3d: OFFSET .*; "
                                          r"c3d: inconsistent scale factor! -1\.0 header"):
        read_c3d(tmp_path / "seed.c3d")


def test_c3d_package_geometry_must_match_the_checks(monkeypatch: pytest.MonkeyPatch) -> None:
    """If the package would read frames of another size than the checks measured (here a patched reader
    with 3 analog samples a frame instead of 4), its values are not the file's: a FormatError naming the
    file, not a shifted clip."""
    import c3d

    monkeypatch.setattr(c3d.Reader, "analog_per_frame", property(lambda self: 3))
    path = data_path(EB015["si"])
    with pytest.raises(FormatError, match=r"Eb015si\.c3d: c3d reads 26 points, 48 analog values a frame "
                                          r"\(integer storage\) where the file holds 26 points, 64 analog"):
        read_c3d_package(path, check_c3d_file(path))


HANG = """
import sys
from mocapz.errors import FormatError
from mocapz.io.c3d import read_c3d
try:
    read_c3d(sys.argv[1])
except FormatError as exc:
    print(exc)
"""


def test_empty_strings_without_end_are_refused(tmp_path: Path) -> None:
    """A char parameter of length 0 declaring 255**3 strings (it takes no bytes) makes readers loop over
    each one (ezc3d and the c3d package hang): the checks refuse it. In a child process with a timeout."""
    _, data = _seed(tmp_path)
    at = data.index(b"LABELS", (data[0] - 1) * 512) + 6  # offset (2), type, dimension count, dimensions
    assert data[at + 2:at + 4] == bytes([255, 2]) and data[at + 6:at + 9] == b"ABC"
    b = bytearray(data)
    b[at + 3:at + 9] = bytes([4, 0, 255, 255, 255, 0])  # 4 dimensions (0, 255, 255, 255), no description
    (tmp_path / "strings.c3d").write_bytes(bytes(b))
    run = subprocess.run([sys.executable, "-c", HANG, str(tmp_path / "strings.c3d")],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "parameter 'LABELS' declares 16581375 strings of length 0" in run.stdout


def test_frames_without_data_are_bounded() -> None:
    """With no point and no analog channel the file size cannot check the frame count: a float POINT:FRAMES of
    2**31 would make both readers loop over empty frames. The checks refuse a count over 16 bits."""
    import struct as _struct

    from mocapz.io.c3d_checks import C3DHeader, C3DParam, _data_layout

    h = C3DHeader(param_block=2, param_blocks=1, processor=84, points=0, first_frame=1, last_frame=1,
                  is_float=True, data_start=3, analog_samples=0, rate=100.0, scale=-1.0)
    params = {("POINT", "USED"): C3DParam(2, (), _struct.pack("<h", 0)),
              ("POINT", "FRAMES"): C3DParam(4, (), _struct.pack("<f", 2.0**31))}
    with pytest.raises(FormatError, match="2147483648 frames declared with no point and no analog channel"):
        _data_layout(h, params, 3 * 512, Path("empty_frames.c3d"))
    params[("POINT", "FRAMES")] = C3DParam(2, (), _struct.pack("<h", 12))
    assert _data_layout(h, params, 3 * 512, Path("empty_frames.c3d")).frames == 12
