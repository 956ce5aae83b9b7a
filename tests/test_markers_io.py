"""C3D (ezc3d) and TRC readers and writers on the shared marker files: loading, round trips, conversion
between the two formats, bad input, safe output, and the CMU 01_01 C3D-versus-AMC root cross-check."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

from mocapz.errors import FormatError, MocapzError
from mocapz.io.c3d import read_c3d, write_c3d
from mocapz.io.trc import read_trc, write_trc
from mocapz.model.motion import MarkerMotion

CMU_C3D = "cmu/c3d/01_01.c3d"
LAB_C3D = "other/markers/pyomeca/markers_analogs.c3d"
GAIT_TRC = "other/markers/btkdata/Gait.trc"
CMU_AMC = "cmu/asfamc/01_01.amc"
AMC_TO_MM = 25.4 / 0.45  # CMU ASF "length 0.45": 1 unit = 1/0.45 inch

# (file, markers, frames, rate Hz, units, share of missing samples) -- MANIFEST.md figures, except that
# Gait.trc holds 105 marker columns (33 named + 72 unnamed) where its header says NumMarkers 66.
MARKER_FILES = [
    (CMU_C3D, 42, 2751, 120.0, "mm", 0.024),
    (LAB_C3D, 51, 580, 100.0, "mm", 0.0103),
    (GAIT_TRC, 105, 487, 100.0, "mm", 0.763),
]


def load(rel: str) -> MarkerMotion:
    path = data_path(rel)
    return read_c3d(path) if path.suffix == ".c3d" else read_trc(path)


@pytest.fixture(scope="module")
def cmu() -> MarkerMotion:
    return load(CMU_C3D)


@pytest.fixture(scope="module")
def lab() -> MarkerMotion:
    return load(LAB_C3D)


@pytest.fixture(scope="module")
def gait() -> MarkerMotion:
    return load(GAIT_TRC)


def small_motion(frames: int = 12, markers: int = 3, seed: int = 0) -> MarkerMotion:
    """A tiny clip with a gap, written from scratch (no source metadata)."""
    rng = np.random.default_rng(seed)
    pos = np.round(rng.normal(0.0, 500.0, (frames, markers, 3)), 3)
    pos[2:5, 1] = np.nan
    return MarkerMotion([f"M{i}" for i in range(markers)], pos, 100.0, "mm", name="small", decimals=3)


def assert_same_markers(a: MarkerMotion, b: MarkerMotion, exact: bool = True) -> None:
    assert a.labels == b.labels
    assert a.frame_rate == b.frame_rate
    assert a.units == b.units
    np.testing.assert_array_equal(a.missing, b.missing)
    want = a.positions if exact else a.positions.astype(np.float32).astype(np.float64)
    np.testing.assert_array_equal(b.positions, want)


# ----------------------------------------------------------------------------------------------- loading


@pytest.mark.parametrize("rel,markers,frames,rate,units,missing", MARKER_FILES)
def test_shared_marker_files_load(rel: str, markers: int, frames: int, rate: float, units: str,
                                  missing: float) -> None:
    m = load(rel)
    assert (m.n_markers, m.n_frames, m.frame_rate, m.units) == (markers, frames, rate, units)
    assert m.positions.shape == (frames, markers, 3) and m.positions.dtype == np.float64
    assert m.missing.mean() == pytest.approx(missing, abs=0.001)
    assert len(set(m.labels)) == markers
    assert m.unit_cm == 0.1
    assert np.isnan(m.positions[m.missing]).all(), "a missing sample is NaN on all three axes"
    assert np.isfinite(m.positions[~m.missing]).all()


def test_cmu_c3d_contents(cmu: MarkerMotion) -> None:
    assert cmu.labels[:4] == ["LBWT", "RBWT", "LFWT", "LTHI"]
    assert cmu.source_format == "c3d" and cmu.decimals is None
    assert cmu.metadata["first_frame"] == 40
    assert cmu.metadata["point_descriptions"][0] == "Left back waist"
    assert "analogs" not in cmu.metadata
    finite = cmu.positions[~cmu.missing]
    np.testing.assert_array_equal(finite, finite.astype(np.float32))  # float C3D: float32 values


def test_c3d_gaps_match_ezc3d_residuals(cmu: MarkerMotion) -> None:
    import ezc3d

    raw = ezc3d.c3d(str(data_path(CMU_C3D)))
    residuals = raw["data"]["meta_points"]["residuals"][0].T
    nan = np.isnan(raw["data"]["points"][:3]).any(axis=0).T
    np.testing.assert_array_equal(cmu.missing, (residuals < 0) | nan)
    assert cmu.missing.sum() == 2773


def test_lab_c3d_keeps_analogs(lab: MarkerMotion) -> None:
    meta = lab.metadata
    assert meta["analogs"].shape == (38, 580 * 20)
    assert meta["analog_rate"] == 2000.0
    assert len(meta["analog_labels"]) == 38 and meta["analog_labels"][0] == "Voltage.1"
    assert meta["analog_units"][0] == "V"
    assert lab.labels[0] == "boite:gauche_ext"


def test_gait_trc_contents(gait: MarkerMotion) -> None:
    assert gait.labels[:3] == ["R.Shoulder", "R.Offset", "R.Elbow"]
    assert gait.labels[32] == "PX" and gait.labels[33] == "*34" and gait.labels[-1] == "*105"
    assert gait.metadata["trc_unnamed"] == list(range(33, 105))
    assert gait.metadata["trc_num_markers_declared"] == 66
    assert gait.decimals == 5 and gait.metadata["trc_time_decimals"] == 3
    assert gait.metadata["first_frame"] == 1 and gait.metadata["trc_newline"] == "\r\n"
    np.testing.assert_array_equal(gait.metadata["trc_frame_numbers"], np.arange(1, 488))
    np.testing.assert_allclose(gait.metadata["trc_times"], np.arange(487) / 100.0, atol=1e-12)
    # frame 1: only the unnamed column 67 has data; frame 160: R.Shoulder
    np.testing.assert_array_equal(gait.positions[0, 66], [4012.05127, 112.96879, 1347.57288])
    assert gait.missing[0, :66].all()
    np.testing.assert_array_equal(gait.positions[159, 0], [1860.02161, 130.71878, 1334.42603])


# ----------------------------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("rel", [CMU_C3D, LAB_C3D])
def test_c3d_round_trip(rel: str, tmp_path: Path) -> None:
    src = load(rel)
    out = tmp_path / "out.c3d"
    write_c3d(src, out)
    back = read_c3d(out)
    assert_same_markers(src, back, exact=True)  # the source is a float C3D: bit-exact
    assert back.metadata["first_frame"] == src.metadata["first_frame"]
    np.testing.assert_array_equal(back.metadata["residuals"], src.metadata["residuals"])
    assert back.metadata["point_descriptions"] == src.metadata["point_descriptions"]
    for key in ("analog_rate", "analog_labels", "analog_units", "analog_descriptions"):
        assert back.metadata.get(key) == src.metadata.get(key)
    if "analogs" in src.metadata:
        np.testing.assert_array_equal(back.metadata["analogs"], src.metadata["analogs"])
    assert sorted(os.listdir(tmp_path)) == ["out.c3d"], "no temporary file left behind"


def test_trc_round_trip(gait: MarkerMotion, tmp_path: Path) -> None:
    out = tmp_path / "out.trc"
    write_trc(gait, out)
    back = read_trc(out)
    assert_same_markers(gait, back, exact=True)
    assert back.decimals == gait.decimals
    for key in ("trc_frame_numbers", "trc_times"):
        np.testing.assert_array_equal(back.metadata[key], gait.metadata[key])
    raw = out.read_bytes()
    assert raw.count(b"\r\n") == raw.count(b"\n"), "CRLF line ends kept"
    lines = raw.decode().split("\r\n")
    assert lines[0] == "PathFileType\t4\t(X/Y/Z)\tgait2.trc"
    assert lines[2] == "100.00\t100.00\t487\t105\tmm\t100.00\t1\t487"
    assert lines[3].startswith("Frame#\tTime\tR.Shoulder\t\t\tR.Offset\t\t\t")
    assert lines[4].startswith("\t\tX1\tY1\tZ1\tX2\t") and lines[5] == ""
    assert lines[6].startswith("1\t0.000\t\t\t")
    again = tmp_path / "again.trc"
    write_trc(back, again)
    assert again.read_bytes() == raw, "writing what was read gives the same bytes"


def test_small_motion_round_trips_without_metadata(tmp_path: Path) -> None:
    m = small_motion()
    write_c3d(m, tmp_path / "s.c3d")
    write_trc(m, tmp_path / "s.trc")
    c3d, trc = read_c3d(tmp_path / "s.c3d"), read_trc(tmp_path / "s.trc")
    assert_same_markers(m, c3d, exact=False)
    assert_same_markers(m, trc, exact=True)
    assert c3d.metadata["first_frame"] == 1 and trc.metadata["first_frame"] == 1
    assert trc.decimals == 3
    np.testing.assert_allclose(trc.metadata["trc_times"], np.arange(12) / 100.0)


def test_many_markers_use_labels2(tmp_path: Path) -> None:
    m = small_motion(frames=4, markers=300)
    write_c3d(m, tmp_path / "many.c3d")
    back = read_c3d(tmp_path / "many.c3d")
    assert back.labels == m.labels  # POINT:LABELS + POINT:LABELS2
    assert_same_markers(m, back, exact=False)


# ----------------------------------------------------------------------------------------------- conversions


def test_trc_to_c3d_and_back(gait: MarkerMotion, tmp_path: Path) -> None:
    write_c3d(gait, tmp_path / "gait.c3d")
    c3d = read_c3d(tmp_path / "gait.c3d")
    assert_same_markers(gait, c3d, exact=False)  # C3D stores float32
    assert c3d.metadata["first_frame"] == 1
    write_trc(c3d, tmp_path / "gait2.trc")
    trc = read_trc(tmp_path / "gait2.trc")
    assert_same_markers(c3d, trc, exact=True)  # float32 values written as exact decimal text
    write_c3d(trc, tmp_path / "gait2.c3d")
    assert_same_markers(c3d, read_c3d(tmp_path / "gait2.c3d"), exact=True)


@pytest.mark.parametrize("rel", [CMU_C3D, LAB_C3D])
def test_c3d_to_trc_and_back(rel: str, tmp_path: Path) -> None:
    src = load(rel)
    write_trc(src, tmp_path / "m.trc")
    trc = read_trc(tmp_path / "m.trc")
    assert_same_markers(src, trc, exact=True)
    assert trc.metadata["first_frame"] == src.metadata["first_frame"]
    np.testing.assert_allclose(np.diff(trc.metadata["trc_times"]), 1.0 / src.frame_rate, atol=1e-6)
    write_c3d(trc, tmp_path / "m.c3d")
    assert_same_markers(src, read_c3d(tmp_path / "m.c3d"), exact=True)


# ----------------------------------------------------------------------------------------------- bad C3D


def _c3d_bytes(rel: str) -> bytes:
    return data_path(rel).read_bytes()


def _corrupt_dims(data: bytes) -> bytes:
    """Give the first ``USED`` parameter 200 dimensions (ezc3d would read far past the record)."""
    b = bytearray(data)
    at = data.index(b"USED", (b[0] - 1) * 512) + 4 + 3  # name, offset (2), type (1) -> dimension count
    b[at] = 200
    return bytes(b)


def _bad_analog_count(data: bytes) -> bytes:
    """Declare 200 analog channels in ANALOG:USED without any SCALE/OFFSET for them."""
    b = bytearray(data)
    group = data.index(b"ANALOG", (b[0] - 1) * 512)
    at = data.index(b"USED", group) + 4 + 4  # name, offset (2), type (1), dimension count 0 -> value
    b[at:at + 2] = (200).to_bytes(2, "little")
    return bytes(b)


BAD_C3D = {
    "empty": lambda: b"",
    "garbage": lambda: bytes(np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8)),
    "text": lambda: b"PathFileType\t4\n" * 100,
    "key_only": lambda: b"\x02\x50" + bytes(np.random.default_rng(2).integers(0, 256, 4000, dtype=np.uint8)),
    "header_only": lambda: _c3d_bytes(CMU_C3D)[:512],
    "cut_in_parameters": lambda: _c3d_bytes(CMU_C3D)[:1536],
    "cut_in_half": lambda: _c3d_bytes(CMU_C3D)[: 1854816 // 2],
    "last_bytes_missing": lambda: _c3d_bytes(CMU_C3D)[:-100],
    "analogs_cut": lambda: _c3d_bytes(LAB_C3D)[:-5000],
    "bad_processor": lambda: _c3d_bytes(CMU_C3D)[:515] + b"\x10" + _c3d_bytes(CMU_C3D)[516:],
    "bad_parameter_dims": lambda: _corrupt_dims(_c3d_bytes(CMU_C3D)),
    "analog_used_without_scales": lambda: _bad_analog_count(_c3d_bytes(CMU_C3D)),
}


@pytest.mark.parametrize("case", sorted(BAD_C3D))
def test_bad_c3d_gives_format_error(case: str, tmp_path: Path) -> None:
    path = tmp_path / f"{case}.c3d"
    path.write_bytes(BAD_C3D[case]())
    with pytest.raises(FormatError) as err:
        read_c3d(path)
    assert str(path) in str(err.value)


def test_missing_c3d_and_folder(tmp_path: Path) -> None:
    with pytest.raises(FormatError, match="no such file"):
        read_c3d(tmp_path / "nope.c3d")
    folder = tmp_path / "dir.c3d"
    folder.mkdir()
    with pytest.raises(FormatError, match="folder"):
        read_c3d(folder)


FUZZ = """
import sys
import numpy as np
from mocapz.errors import FormatError
from mocapz.io.c3d import read_c3d
src = open(sys.argv[1], "rb").read()
rng = np.random.default_rng(int(sys.argv[3]))
end = min(len(src), 512 * 4)
for i in range(int(sys.argv[4])):
    b = bytearray(src)
    for pos in rng.integers(0, end, rng.choice([1, 2, 4])):
        b[pos] = rng.choice([0, 1, 0x7F, 0x80, 0xFF, int(rng.integers(256))])
    path = sys.argv[2] + f"/f{i}.c3d"
    open(path, "wb").write(bytes(b))
    try:
        read_c3d(path)
    except FormatError:
        pass
print("done")
"""


def test_corrupted_c3d_never_crashes(tmp_path: Path) -> None:
    """Random byte changes in the header and parameters: FormatError or a clip, never a crash or hang.

    Runs in a child process, so that an ezc3d segfault fails this test instead of killing pytest.
    """
    m = small_motion(frames=6, markers=2)
    m.metadata.update(analogs=np.arange(2 * 60, dtype=float).reshape(2, 60), analog_rate=1000.0,
                      analog_labels=["a1", "a2"])
    write_c3d(m, tmp_path / "seed.c3d")
    (tmp_path / "fuzz").mkdir()
    run = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(FUZZ), str(tmp_path / "seed.c3d"), str(tmp_path / "fuzz"),
         "5", "400"],
        capture_output=True, text=True, timeout=300,
    )
    assert run.returncode == 0, f"child died (code {run.returncode}): {run.stderr[-2000:]}"
    assert run.stdout.strip().endswith("done")


# ----------------------------------------------------------------------------------------------- bad TRC

GOOD_TRC = (
    "PathFileType\t4\t(X/Y/Z)\tt.trc\n"
    "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
    "50.00\t50.00\t3\t2\tm\t50.00\t1\t3\n"
    "Frame#\tTime\tA\t\t\tB\t\t\t\n"
    "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\t\n"
    "\n"
    "1\t0.00\t1.5\t2.5\t3.5\t\t\t\n"
    "2\t0.02\t1.6\t2.6\t3.6\t4.0\t5.0\t6.0\n"
    "3\t0.04\t1.7\t2.7\t3.7\t4.1\t5.1\t6.1\n"
)


def test_small_trc_parses(tmp_path: Path) -> None:
    path = tmp_path / "t.trc"
    path.write_text(GOOD_TRC)
    m = read_trc(path)
    assert (m.labels, m.units, m.frame_rate, m.decimals) == (["A", "B"], "m", 50.0, 1)
    assert m.unit_cm == 100.0
    np.testing.assert_array_equal(m.missing, [[False, True], [False, False], [False, False]])
    np.testing.assert_array_equal(m.positions[2], [[1.7, 2.7, 3.7], [4.1, 5.1, 6.1]])


def test_trc_variants_parse(tmp_path: Path) -> None:
    """No blank line, trailing markers left off a row, spaces around fields, NaN text, CRLF."""
    lines = GOOD_TRC.splitlines()
    del lines[5]
    lines[5] = "1\t0.00\t 1.5 \t2.5\t3.5"
    lines[6] = "2\t0.02\tNaN\tNaN\tNaN\t4.0\t5.0\t6.0"
    path = tmp_path / "v.trc"
    path.write_bytes("\r\n".join(lines).encode() + b"\r\n")
    m = read_trc(path)
    np.testing.assert_array_equal(m.missing, [[False, True], [True, False], [False, False]])
    assert m.positions[0, 0, 0] == 1.5
    assert m.metadata["trc_blank_line"] is False and m.metadata["trc_newline"] == "\r\n"


def _trc_edit(line: int, text: str | None) -> str:
    lines = GOOD_TRC.splitlines()
    if text is None:
        del lines[line - 1]
    else:
        lines[line - 1] = text
    return "\n".join(lines) + "\n"


# (case, file text, expected line of the error, message fragment)
BAD_TRC = [
    ("empty", "", None, "empty"),
    ("not_trc", "hello\tworld\n1\t2\n", 1, "PathFileType"),
    ("header_cut", "\n".join(GOOD_TRC.splitlines()[:3]), 3, "truncated header"),
    ("frames_too_many", _trc_edit(3, "50.00\t50.00\t5\t2\tm\t50.00\t1\t3"), 9, "NumFrames"),
    ("frames_too_few", _trc_edit(3, "50.00\t50.00\t2\t2\tm\t50.00\t1\t3"), 9, "NumFrames"),
    ("rows_cut", "\n".join(GOOD_TRC.splitlines()[:8]) + "\n", 8, "truncated"),
    ("markers_too_many", _trc_edit(3, "50.00\t50.00\t3\t4\tm\t50.00\t1\t3"), 3, "NumMarkers"),
    ("markers_too_few", _trc_edit(3, "50.00\t50.00\t3\t1\tm\t50.00\t1\t3"), 3, "NumMarkers"),
    ("non_numeric", _trc_edit(8, "2\t0.02\t1.6\t2.6\tabc\t4.0\t5.0\t6.0"), 8, "non-numeric"),
    ("comma_decimal", _trc_edit(9, "3\t0.04\t1,7\t2.7\t3.7\t4.1\t5.1\t6.1"), 9, "non-numeric"),
    ("partial_sample", _trc_edit(9, "3\t0.04\t1.7\t\t3.7\t4.1\t5.1\t6.1"), 9, "X/Y/Z"),
    ("missing_time", _trc_edit(8, "2\t\t1.6\t2.6\t3.6\t4.0\t5.0\t6.0"), 8, "time"),
    ("infinite", _trc_edit(8, "2\t0.02\t1e999\t2.6\t3.6\t4.0\t5.0\t6.0"), 8, "infinite"),
    ("no_rate", _trc_edit(2, "CameraRate\tX\tNumFrames\tNumMarkers\tUnits\tA\tB\tC"), 2, "DataRate"),
    ("zero_rate", _trc_edit(3, "0\t50.00\t3\t2\tm\t50.00\t1\t3"), 3, "DataRate"),
    ("values_short", _trc_edit(3, "50.00\t50.00\t3\t2"), 3, "keywords"),
    ("no_name_row", _trc_edit(4, "1\t0.00\t1.5\t2.5\t3.5"), 4, "name row"),
    ("binary", "PathFileType\x00\x01\x02", None, "binary"),
]


@pytest.mark.parametrize("case,text,line,fragment", BAD_TRC, ids=[c[0] for c in BAD_TRC])
def test_bad_trc_gives_format_error(case: str, text: str, line: int | None, fragment: str,
                                    tmp_path: Path) -> None:
    path = tmp_path / f"{case}.trc"
    path.write_text(text)
    with pytest.raises(FormatError, match=fragment) as err:
        read_trc(path)
    assert err.value.path == str(path)
    assert err.value.line == line


def test_truncated_gait_trc(tmp_path: Path) -> None:
    raw = data_path(GAIT_TRC).read_bytes()
    for cut in (len(raw) // 2, len(raw) - 3000, 300):
        path = tmp_path / f"cut{cut}.trc"
        path.write_bytes(raw[:cut])
        with pytest.raises(FormatError) as err:
            read_trc(path)
        assert str(path) in str(err.value) and err.value.line is not None


def test_missing_trc_and_folder(tmp_path: Path) -> None:
    with pytest.raises(FormatError, match="no such file"):
        read_trc(tmp_path / "nope.trc")
    with pytest.raises(FormatError, match="folder"):
        read_trc(tmp_path)


# ----------------------------------------------------------------------------------------------- safe output


def test_failed_writes_leave_nothing(tmp_path: Path) -> None:
    too_big = small_motion()
    too_big.positions[0, 0, 0] = 1e39  # beyond float32
    cases = [
        (write_c3d, too_big, "x.c3d", "float32"),
        (write_c3d, small_motion(frames=0), "x.c3d", "without frames"),
        (write_c3d, MarkerMotion(["é"], np.zeros((2, 1, 3)), 100.0), "x.c3d", "ASCII"),
        (write_trc, MarkerMotion(["a\tb"], np.zeros((2, 1, 3)), 100.0), "x.trc", "tabs"),
        (write_trc, MarkerMotion(["a"], np.zeros((2, 1, 3)), 0.0), "x.trc", "rate"),
    ]
    for write, motion, name, fragment in cases:
        with pytest.raises(FormatError, match=fragment):
            write(motion, tmp_path / name)
        assert os.listdir(tmp_path) == []


def test_failure_inside_ezc3d_write_cleans_up(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import ezc3d

    def broken_write(self: object, path: str, **kwargs: object) -> None:
        Path(path).write_bytes(b"partial")
        raise RuntimeError("disk full")

    monkeypatch.setattr(ezc3d.c3d, "write", broken_write)
    with pytest.raises(FormatError, match="disk full"):
        write_c3d(small_motion(), tmp_path / "x.c3d")
    assert os.listdir(tmp_path) == []


def test_c3d_frame_limit(tmp_path: Path) -> None:
    long = MarkerMotion(["a"], np.zeros((65536, 1, 3)), 100.0)
    with pytest.raises(FormatError, match="65535"):
        write_c3d(long, tmp_path / "long.c3d")
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("write,read,name", [(write_c3d, read_c3d, "o.c3d"), (write_trc, read_trc, "o.trc")])
def test_existing_output_needs_force(write: Callable[..., None], read: Callable[[Path], MarkerMotion],
                                     name: str, tmp_path: Path) -> None:
    out = tmp_path / name
    out.write_bytes(b"keep me")
    with pytest.raises(MocapzError, match="exists"):
        write(small_motion(), out)
    assert out.read_bytes() == b"keep me"
    write(small_motion(), out, force=True)
    assert read(out).n_frames == 12
    assert sorted(os.listdir(tmp_path)) == [name]


def test_mismatched_analogs_are_dropped_with_a_warning(lab: MarkerMotion, tmp_path: Path) -> None:
    cut = MarkerMotion(lab.labels, lab.positions[:100], lab.frame_rate, lab.units, metadata=dict(lab.metadata))
    cut.metadata.pop("residuals")
    with pytest.warns(UserWarning, match="analog"):
        write_c3d(cut, tmp_path / "cut.c3d")
    back = read_c3d(tmp_path / "cut.c3d")
    assert back.n_frames == 100 and "analogs" not in back.metadata


# ----------------------------------------------------------------------------------------------- cross-check


def amc_root_positions(path: Path) -> np.ndarray:
    """``(frames, 3)`` root translation of every AMC frame, in AMC units."""
    rows = [line.split()[1:4] for line in path.read_text().splitlines() if line.startswith("root ")]
    return np.array(rows, dtype=np.float64)


def test_cmu_pelvis_markers_follow_amc_root(cmu: MarkerMotion) -> None:
    """The pelvis-marker centroid of 01_01.c3d tracks the AMC root: C3D (X, Y, Z) = AMC (Z, X, Y)."""
    root = amc_root_positions(data_path(CMU_AMC)) * AMC_TO_MM
    assert root.shape == (cmu.n_frames, 3)
    pelvis = cmu.positions[:, [cmu.labels.index(n) for n in ("LFWT", "RFWT", "LBWT", "RBWT")]]
    ok = np.isfinite(pelvis).all(axis=(1, 2))
    assert ok.mean() > 0.99
    centroid = pelvis[ok].mean(axis=1)
    root = root[ok]
    corr = np.array([[np.corrcoef(centroid[:, i], root[:, j])[0, 1] for j in range(3)] for i in range(3)])
    mapping = np.abs(corr).argmax(axis=1)
    signs = np.sign(corr[np.arange(3), mapping])
    assert mapping.tolist() == [2, 0, 1] and signs.tolist() == [1, 1, 1]
    best = np.abs(corr[np.arange(3), mapping])
    assert (best >= 0.99).all(), best
    mapped = root[:, mapping] * signs
    slopes = np.array([np.polyfit(mapped[:, i], centroid[:, i], 1)[0] for i in range(3)])
    extent = np.ptp(mapped, axis=0)
    assert abs(slopes[extent.argmax()] - 1.0) < 0.01, slopes  # same scale: mm = AMC units x 25.4/0.45
    assert ((slopes > 0.9) & (slopes < 1.2)).all(), slopes
    offset = np.linalg.norm((centroid - mapped).mean(axis=0))
    assert offset < 150.0  # mm: the root joint sits inside the pelvis
