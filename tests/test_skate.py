"""Foot skate (frame to frame and over 0.1 s windows) and jitter on real clips: zero for a lossless round
trip, the made slide of a planted foot read back exactly, white noise read back as its expected energy."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import data_path

from mocapz import compress, decompress, evaluate
from mocapz.cli.main import cli
from mocapz.io import load
from mocapz.metrics.contacts import Contacts, find_contacts
from mocapz.metrics.skate import foot_skates, full_windows, jitter_pct, window_steps
from mocapz.model.motion import MarkerMotion, Motion

WALK = "cmu/bvh/02_01.bvh"  # 344 frames of walking at 120 fps
TRC = "other/markers/btkdata/Gait.trc"


@pytest.fixture(scope="module")
def walk() -> Motion:
    m = load(data_path(WALK))
    assert isinstance(m, Motion)
    return m


def _pin(a: np.ndarray, con: Contacts) -> np.ndarray:
    """``a`` with each foot held horizontally where its run of planted steps began (heights kept)."""
    out = a.copy()
    n = a.shape[0] - 1
    for i, f in enumerate(con.feet):
        st = con.steps[:, i]
        starts = st & ~np.concatenate([[False], st[:-1]])
        run_start = np.maximum.accumulate(np.where(starts, np.arange(n), 0))
        k = np.flatnonzero(st)
        for ax in con.horizontal:
            out[k + 1, f, ax] = a[run_start[k], f, ax]
    return out


def _planted_walk(walk: Motion) -> tuple[np.ndarray, np.ndarray, Contacts]:
    """The walk's positions with planted feet made perfectly still, its validity mask and its contacts."""
    a = walk.positions()
    valid = np.ones(a.shape[:2], dtype=bool)
    con = find_contacts(walk, a, valid, walk.skeleton.unit_cm)
    for _ in range(10):  # pinning can make a neighbouring step slow enough to count: pin until stable
        a = _pin(a, con)
        again = find_contacts(walk, a, valid, walk.skeleton.unit_cm)
        if np.array_equal(again.steps, con.steps):
            break
        con = again
    assert np.array_equal(find_contacts(walk, a, valid, walk.skeleton.unit_cm).steps, con.steps)
    assert con.steps.all(axis=0).sum() == 0 and con.steps.any(axis=0).all()  # both feet planted, not always
    w = window_steps(walk.frame_rate)
    assert any(full_windows(con.steps[:, i], w).any() for i in range(con.feet.size))  # a planted 0.1 s
    return a, valid, con


def _run_offsets(con: Contacts, i: int, n_frames: int) -> np.ndarray:
    """``(frames,)`` frames since the start of foot ``i``'s planted run (0 outside runs and on run starts)."""
    st = con.steps[:, i]
    starts = st & ~np.concatenate([[False], st[:-1]])
    run_start = np.maximum.accumulate(np.where(starts, np.arange(st.size), 0))
    off = np.zeros(n_frames)
    k = np.flatnonzero(st)
    off[k + 1] = k + 1 - run_start[k]
    return off


def test_window_steps_andfull_windows() -> None:
    assert window_steps(120.0) == 12 and window_steps(30.0) == 3 and window_steps(5.0) == 1
    steps = np.array([1, 1, 1, 0, 1, 1, 1, 1, 0], dtype=bool)
    # windows of 3 steps from frames 0..6: only those from frames 0, 4 and 5 lie in planted steps
    assert full_windows(steps, 3).tolist() == [True, False, False, False, True, True, False]
    assert full_windows(steps, 1).tolist() == steps.tolist()


def test_lossless_round_trip_gives_zero_skate_and_jitter(walk: Motion) -> None:
    rep = evaluate(walk, decompress(compress(walk, codec="lossless")))
    assert (rep.foot_skate, rep.foot_skate_window, rep.jitter_pct) == (0.0, 0.0, 0.0)
    markers = load(data_path(TRC))
    assert isinstance(markers, MarkerMotion) and markers.missing.any()
    rep = evaluate(markers, decompress(compress(markers, codec="lossless")))
    assert (rep.foot_skate, rep.foot_skate_window, rep.jitter_pct) == (0.0, 0.0, 0.0)
    assert rep.as_dict()["foot_skate_window_cm_per_s"] == 0.0


def test_planted_foot_slide_reads_as_its_speed(walk: Motion) -> None:
    """Each planted foot slides at 4 cm/s (along the first horizontal axis) for as long as it is planted:
    both skate figures read 4 cm/s exactly."""
    a, valid, con = _planted_walk(walk)
    speed = 4.0 / walk.skeleton.unit_cm  # file units per second
    b = a.copy()
    for i, f in enumerate(con.feet):
        b[:, f, con.horizontal[0]] += speed * _run_offsets(con, i, a.shape[0]) / walk.frame_rate
    skate, window = foot_skates(walk, a, b, valid, walk.skeleton.unit_cm)
    assert skate == pytest.approx(speed, rel=1e-9)
    assert window == pytest.approx(speed, rel=1e-9)
    assert jitter_pct(a, b, valid) > 0.0


def test_planted_foot_trembling_is_skate_frame_to_frame_only(walk: Motion) -> None:
    """A planted foot shaking by +-1 mm every frame: 2 mm per frame step frame to frame, nothing over the
    0.1 s windows (12 steps at 120 fps: an even count, the shake cancels)."""
    a, valid, con = _planted_walk(walk)
    delta = 0.1 / walk.skeleton.unit_cm
    sign = np.where(np.arange(a.shape[0]) % 2 == 0, 1.0, -1.0)
    b = a.copy()
    planted = con.frames()
    for i, f in enumerate(con.feet):
        b[:, f, con.horizontal[1]] += np.where(planted[:, i], delta * sign, 0.0)
    skate, window = foot_skates(walk, a, b, valid, walk.skeleton.unit_cm)
    assert window_steps(walk.frame_rate) % 2 == 0
    assert skate == pytest.approx(2 * delta * walk.frame_rate, rel=1e-9)
    assert window == pytest.approx(0.0, abs=1e-9)


def test_white_noise_on_markers_gives_its_expected_jitter() -> None:
    """Noise of deviation s on every coordinate adds about 6 s^2 per coordinate and second difference."""
    m = load(data_path(TRC))
    assert isinstance(m, MarkerMotion)
    a, valid = m.positions, ~m.missing
    s = 1.0  # mm
    noisy = a + np.random.default_rng(5).normal(scale=s, size=a.shape)
    ok = valid[2:] & valid[1:-1] & valid[:-2]
    acc = a[2:] - 2 * a[1:-1] + a[:-2]
    energy = float(np.sum(np.where(ok, np.sum(np.nan_to_num(acc) ** 2, axis=-1), 0.0)))
    expected = 100.0 * 18 * s**2 * ok.sum() / energy
    rep = evaluate(m, m.with_positions(noisy))
    assert rep.jitter_pct == pytest.approx(expected, rel=0.1)
    assert expected > 5.0


def test_noise_on_skeletal_channels_gives_jitter_and_skate(walk: Motion) -> None:
    ch = walk.channels + np.random.default_rng(3).normal(scale=0.3, size=walk.channels.shape)
    rep = evaluate(walk, walk.with_channels(ch))
    assert rep.jitter_pct is not None and rep.jitter_pct > 5.0
    assert rep.foot_skate is not None and rep.foot_skate > 0.0
    assert rep.foot_skate_window is not None and abs(rep.foot_skate_window) < rep.foot_skate


def test_eval_command_prints_the_three_figures(tmp_path: Path, walk: Motion) -> None:
    src = data_path(WALK)
    mcz = tmp_path / "walk.mcz"
    mcz.write_bytes(compress(walk, codec="quant", max_error="1cm"))
    out = CliRunner().invoke(cli, ["eval", str(src), str(mcz), "--json"], catch_exceptions=False)
    d = json.loads(out.output)
    for k in ("foot_skate", "foot_skate_window", "jitter_pct", "foot_skate_cm_per_s",
              "foot_skate_window_cm_per_s"):
        assert isinstance(d[k], float), k
    assert d["foot_skate_cm_per_s"] == pytest.approx(d["foot_skate"] * walk.skeleton.unit_cm)
    text = CliRunner().invoke(cli, ["eval", str(src), str(mcz)], catch_exceptions=False).output
    assert "foot_skate_window" in text and "jitter_pct" in text and "cm/s" in text
