"""The c3d.org / BTKData C3D samples (MANIFEST: other/markers/btkdata/c3d_samples/): one trial in six
storages gives one motion, mocapz's own decoder (mocapz.io.c3d_tolerant) gives ezc3d's values where
ezc3d reads a file, and the files ezc3d cannot read (SGI/MIPS storage, header errors) or mocapz's
pre-checks used to refuse (a parameter section longer than it declares) are read."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

from mocapz.errors import FormatError
from mocapz.io.c3d import read_c3d, write_c3d
from mocapz.io.c3d_checks import check_c3d_file
from mocapz.io.c3d_tolerant import read_c3d_raw
from mocapz.model.motion import MarkerMotion

SAMPLES = "other/markers/btkdata/c3d_samples"
EB015 = {s: f"{SAMPLES}/Eb015{s}.c3d" for s in ("pi", "pr", "si", "sr", "vi", "vr")}  # PC, SGI, DEC x int, real
EZC3D_READS = [EB015[s] for s in ("pi", "pr", "vi", "vr")] + [
    f"{SAMPLES}/FP1.C3D", f"{SAMPLES}/PiG_Motion-FlatFoot-Full.c3d", "other/markers/pyomeca/markers_analogs.c3d"]


def _load(rel: str) -> MarkerMotion:
    return read_c3d(data_path(rel))


@pytest.fixture(scope="module")
def eb015() -> dict[str, MarkerMotion]:
    return {s: _load(rel) for s, rel in EB015.items()}


def test_eb015_storages_give_one_motion(eb015: dict[str, MarkerMotion]) -> None:
    """Six storages of one trial: same labels, rate, shape, gaps, analogs; the integer files give
    ``int * POINT:SCALE``, the float files its float32 rounding."""
    pi = eb015["pi"]
    assert pi.positions.shape == (450, 26, 3) and pi.frame_rate == 50.0 and pi.units == "mm"
    for s, m in eb015.items():
        assert m.labels == pi.labels and m.frame_rate == pi.frame_rate and m.units == pi.units, s
        np.testing.assert_array_equal(m.missing, pi.missing, err_msg=s)
        np.testing.assert_array_equal(m.metadata["residuals"], pi.metadata["residuals"], err_msg=s)
        np.testing.assert_array_equal(m.metadata["analogs"], pi.metadata["analogs"], err_msg=s)
        want = pi.positions if s.endswith("i") else pi.positions.astype(np.float32).astype(np.float64)
        np.testing.assert_array_equal(m.positions, want, err_msg=s)
        assert m.metadata["c3d_float"] == s.endswith("r")
    assert eb015["si"].metadata["c3d_processor"] == 86 and "MIPS" in eb015["si"].metadata["c3d_reader"]
    assert eb015["pi"].metadata["c3d_reader"] == "ezc3d"


@pytest.mark.parametrize("rel", EZC3D_READS)
def test_tolerant_reader_gives_ezc3d_values(rel: str) -> None:
    """On every sample ezc3d reads, mocapz's decoder gives exactly ezc3d's points, residuals and analogs."""
    import ezc3d

    path = data_path(rel)
    ours = read_c3d_raw(path, check_c3d_file(path))
    theirs = ezc3d.c3d(str(path), extract_forceplat_data=False)
    for key in ("points", "analogs"):
        np.testing.assert_array_equal(ours["data"][key], np.asarray(theirs["data"][key]), err_msg=key)
    np.testing.assert_array_equal(ours["data"]["meta_points"]["residuals"],
                                  np.asarray(theirs["data"]["meta_points"]["residuals"]))
    for key in ("first_frame", "last_frame"):
        assert ours["header"]["points"][key] == theirs["header"]["points"][key]


def test_dance_is_recovered() -> None:
    """Dance.c3d (PhoeniX; POINT:DATA_START 0, empty descriptions, a float ANALOG:OFFSET, POINT:FRAMES 500
    for 499 frames): ezc3d refuses it, mocapz's decoder reads the 499 frames the file holds."""
    m = _load(f"{SAMPLES}/Dance.c3d")
    assert m.positions.shape == (499, 40, 3) and m.units == "mm"
    assert m.frame_rate == pytest.approx(65.0533, abs=1e-4)
    assert m.labels[:2] == ["Channel101", "Channel102"] and m.metadata["point_descriptions"] == [""] * 40
    assert "c3d_tolerant" in m.metadata["c3d_reader"]
    present = m.positions[~m.missing]
    assert present.size and np.isfinite(present).all() and np.abs(present).max() < 3000  # mm, a room
    step = np.linalg.norm(np.diff(m.positions, axis=0), axis=2)
    assert np.nanmedian(step) < 20  # mm per frame at 65 Hz: a body moving, not garbage
    assert m.metadata["analogs"].shape == (8, 499) and np.isfinite(m.metadata["analogs"]).all()


def test_fp1_parameter_section_longer_than_declared() -> None:
    """FP1.C3D declares 3 parameter blocks and fills 5 (its ANALOG:UNITS crosses block 4): ezc3d reads it."""
    m = _load(f"{SAMPLES}/FP1.C3D")
    assert m.positions.shape == (480, 8, 3) and m.frame_rate == 60.0 and m.metadata["c3d_reader"] == "ezc3d"
    assert m.metadata["analogs"].shape == (12, 4800) and m.metadata["analog_rate"] == 600.0


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
    header's frames are read, by mocapz's decoder; a file cut short of the header's count is still refused.
    (Frames that fit in the padding of the last block are data as far as the file can tell.)"""
    seed, data = _seed(tmp_path)
    at = data.index(b"FRAMES", (data[0] - 1) * 512) + 6 + 2 + 2  # name, offset, type, dimension count
    assert struct.unpack("<h", data[at:at + 2])[0] == 7
    b = bytearray(data)
    b[at:at + 2] = struct.pack("<h", 30)  # 23 frames of 48 bytes more: past the 512-byte padding
    (tmp_path / "frames.c3d").write_bytes(bytes(b))
    m = read_c3d(tmp_path / "frames.c3d")
    _same(seed, m)
    assert "POINT:FRAMES (30)" in m.metadata["c3d_reader"]
    end = (struct.unpack("<H", data[16:18])[0] - 1) * 512 + 7 * 3 * 16  # the 7 frames of 3 float points
    (tmp_path / "cut.c3d").write_bytes(bytes(b[:end - 16]))
    with pytest.raises(FormatError, match="truncated"):
        read_c3d(tmp_path / "cut.c3d")


def test_ezc3d_refusal_falls_back(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A file whose structure passes the checks but that ezc3d refuses is read by mocapz's decoder; when
    that fails too, the FormatError names the file and both reasons."""
    import ezc3d

    import mocapz.io.c3d_tolerant as tolerant

    seed, _ = _seed(tmp_path)

    def refuse(*_: object, **__: object) -> None:
        raise RuntimeError("OFFSET parameter is not an INT")

    monkeypatch.setattr(ezc3d, "c3d", refuse)
    m = read_c3d(tmp_path / "seed.c3d")
    _same(seed, m)
    assert m.metadata["c3d_reader"] == "mocapz.io.c3d_tolerant (ezc3d: OFFSET parameter is not an INT)"

    def fail(path: Path, *_: object) -> None:
        raise FormatError(path, "no good")

    monkeypatch.setattr(tolerant, "read_c3d_raw", fail)
    with pytest.raises(FormatError, match=r"seed\.c3d: not a readable C3D file \(ezc3d: OFFSET .*; no good\)"):
        read_c3d(tmp_path / "seed.c3d")
