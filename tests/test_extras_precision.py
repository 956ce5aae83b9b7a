"""A named precision for a C3D file's analog channels and model-output tracks (issue 10): every value comes back
within it in its own unit, whatever the storage (Intel / DEC / MIPS, int16 / float32) and the marker codec;
markers, parameters and residuals stay exact; the file shrinks; names and bad values are checked."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import ezc3d
import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.errors import OptionError
from mocapz.format.container import Container
from mocapz.format.extras_precision import ExtrasPrecision, parse_precision
from mocapz.metrics.c3d_extras import extras_errors

SAMPLES = "other/markers/btkdata/c3d_samples"
PIG = f"{SAMPLES}/PiG_Motion-FlatFoot-Full.c3d"
WITH_ANALOGS = [PIG, "other/markers/pyomeca/markers_analogs.c3d", f"{SAMPLES}/FP1.C3D", f"{SAMPLES}/Eb015vr.c3d",
                f"{SAMPLES}/Eb015sr.c3d", f"{SAMPLES}/Eb015si.c3d", f"{SAMPLES}/Dance.c3d"]
TRACKS = {"angles": 0.01, "forces": 0.05, "moments": 5.0, "powers": 0.01}
KIND_OF = {k.upper(): v for k, v in TRACKS.items()}


def _size(data: bytes, key: str) -> int:
    """Bytes of the ``c3d.<key>`` section, or of its blocks' ``c3d.<key>.<i>``."""
    return sum(len(v) for k, v in Container.from_bytes(data).sections.items()
               if k == f"c3d.{key}" or k.startswith(f"c3d.{key}."))


def _load(rel: str) -> mocapz.MarkerMotion:
    motion = mocapz.load(data_path(rel))
    assert isinstance(motion, mocapz.MarkerMotion)
    return motion


@pytest.mark.parametrize("rel", WITH_ANALOGS)
@pytest.mark.parametrize("precision", [0.01, 1.0])
def test_every_analog_value_within_the_precision(rel: str, precision: float, tmp_path: Path) -> None:
    src = _load(rel)
    exact = mocapz.compress(src, "lossless")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        data = mocapz.compress(src, "lossless", analog_precision=precision, track_precision=TRACKS)
        back = mocapz.decompress(data)
    a, b = src.metadata["c3d"], back.metadata["c3d"]
    err = np.abs(b.analog_values() - a.analog_values()) * a.analog_scales
    assert err.max() <= precision
    np.testing.assert_array_equal(back.positions, src.positions)  # markers: lossless codec, exact
    assert b.params == a.params and b.header == a.header
    np.testing.assert_array_equal(b.residual_words, a.residual_words)
    assert 0 < _size(data, "ana") <= _size(exact, "ana")
    figures = extras_errors(src, back)
    assert figures is not None and figures["analogs"]["max_err"] == pytest.approx(err.max())
    out = tmp_path / "back.c3d"
    mocapz.save(back, out)
    # the written file read again in physical units (offset, scale and gen scale applied: ezc3d's, where it
    # reads the storage), against the source's
    got = mocapz.load(out).metadata["analogs"]
    assert np.abs(got - src.metadata["analogs"]).max() <= precision * (1 + 1e-6)
    if src.metadata["c3d_reader"] == "ezc3d":
        direct = ezc3d.c3d(str(out), extract_forceplat_data=False)["data"]["analogs"][0]
        assert np.abs(direct - src.metadata["analogs"]).max() <= precision * (1 + 1e-6)


def test_precision_pays_on_the_plug_in_gait_trial() -> None:
    """The PiG trial's analogs at 0.01 and its tracks at TRACKS cost well under half of the exact extras."""
    src = _load(PIG)
    exact = mocapz.compress(src, "lossless")
    rounded = mocapz.compress(src, "lossless", analog_precision=0.01, track_precision=TRACKS)
    assert _size(rounded, "ana") < 0.5 * _size(exact, "ana")
    assert _size(rounded, "trk") < 0.5 * _size(exact, "trk")


def test_tracks_within_their_kinds_precision_through_a_lossy_codec() -> None:
    src = _load(PIG).slice(0, 120)
    back = mocapz.decompress(mocapz.compress(src, "quant", max_error="1cm", track_precision=TRACKS))
    a, b = src.metadata["c3d"], back.metadata["c3d"]
    err = np.abs(b.track_values() - a.track_values())
    assert np.isnan(err).sum() == np.isnan(a.track_values()).sum()  # missing samples stay missing
    for kind, p in KIND_OF.items():
        sel = np.array(a.track_kinds) == kind
        assert sel.any()
        assert np.nanmax(err[:, sel]) <= p
        assert not np.array_equal(b.track_words[:, sel], a.track_words[:, sel])  # rounded, not kept
    np.testing.assert_array_equal(b.analog_words, a.analog_words)  # no analog precision: exact


def test_a_precision_finer_than_the_storage_changes_nothing() -> None:
    """Eb015pi stores analogs as int16 counts of 0.43-120 units: 0.01 is finer, so the file is the exact one."""
    src = _load(f"{SAMPLES}/Eb015pi.c3d")
    assert mocapz.compress(src, "lossless", analog_precision=0.01) == mocapz.compress(src, "lossless")


def test_a_label_wins_over_its_kind_and_the_plain_number() -> None:
    extras = _load(PIG).metadata["c3d"]
    p = ExtrasPrecision.of(None, {"": 1.0, "angles": 0.1, extras.track_labels[0]: 0.001})
    assert p is not None
    per = p.per_track(extras.track_labels, extras.track_kinds)
    kinds = np.array(extras.track_kinds)
    assert per[0] == 0.001
    assert (per[1:][kinds[1:] == "ANGLES"] == 0.1).all()
    assert (per[kinds != "ANGLES"] == 1.0).all()
    q = ExtrasPrecision.of({"Fz1": 0.5}, None)
    assert q is not None
    per = q.per_channel(extras.analog_labels)
    assert per[extras.analog_labels.index("Fz1")] == 0.5 and np.count_nonzero(per) == 1


@pytest.mark.parametrize("spec", ["0", "-1", "x", "nan", "inf", "Fz1=", "a=1,a=2"])
def test_bad_precision_values(spec: str) -> None:
    with pytest.raises(OptionError):
        parse_precision(spec, "--analog-precision")


def test_unknown_names_are_refused() -> None:
    with pytest.raises(OptionError, match="no analog channel named nope"):
        mocapz.compress(_load(f"{SAMPLES}/FP1.C3D"), "lossless", analog_precision="nope=1")


def test_cli(tmp_path: Path) -> None:
    src = data_path(f"{SAMPLES}/FP1.C3D")
    run = [sys.executable, "-m", "mocapz.cli.main", "compress", str(src)]
    ok = subprocess.run(run + ["-o", str(tmp_path / "a.mcz"), "--analog-precision", "0.5"],
                        capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert "12 analog channels within" in ok.stderr and "parameters exact" in ok.stderr
    bad = subprocess.run(run + ["-o", str(tmp_path / "b.mcz"), "--analog-precision", "Fz9=1"],
                         capture_output=True, text=True)
    assert bad.returncode == 1 and bad.stderr.count("\n") == 1 and "no analog channel named Fz9" in bad.stderr
    assert not (tmp_path / "b.mcz").exists()
    worse = subprocess.run(run + ["-o", str(tmp_path / "c.mcz"), "--track-precision", "-2"],
                           capture_output=True, text=True)
    assert worse.returncode == 2 and "Traceback" not in worse.stderr
