"""METRICS.md figures against values computed by hand on tiny synthetic motions, plus real-clip sanity."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import data_path

from mocapz import compress, decompress
from mocapz.errors import MocapzError
from mocapz.io.bvh import read_bvh
from mocapz.metrics.figures import (
    arms,
    bone_len_err,
    bone_pairs,
    distortion_pct,
    evaluate,
    point_errors,
    positions_pair,
    size_figures,
)
from mocapz.model.motion import MarkerMotion, Motion
from mocapz.model.skeleton import Skeleton

NAN = float("nan")


def _tiny_skeleton() -> Skeleton:
    """Root ``r`` (XYZ position channels) -> joint ``c`` at (1,0,0) (Xposition, Zrotation) -> end site (1,0,0)."""
    return Skeleton(
        names=["r", "c"],
        parents=np.array([-1, 0]),
        offsets=np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]),
        channels=[("Xposition", "Yposition", "Zposition"), ("Xposition", "Zrotation")],
        rotation_order=["", "Z"],
        end_sites=[(1, np.array([1.0, 0.0, 0.0]), "c_End")],
        unit_cm=2.0,
    )


def _tiny_pair() -> tuple[Motion, Motion]:
    """Original and decoded tiny skeletal motions (2 frames, 10 fps).

    Original points: frame 0 r (0,0,0), c (1,0,0), end (2,0,0); frame 1 (c turned 90 deg about Z)
    r (0,0,0), c (1,0,0), end (1,1,0). Decoded: frame 0 has c's Xposition 2 (bone r-c twice as long),
    so c (2,0,0) and end (3,0,0); frame 1 is exact.
    """
    sk = _tiny_skeleton()
    orig = Motion(sk, np.array([[0, 0, 0, 1, 0], [0, 0, 0, 1, 90]], dtype=float), 10.0, name="tiny")
    dec = orig.with_channels(np.array([[0, 0, 0, 2, 0], [0, 0, 0, 1, 90]], dtype=float))
    return orig, dec


def _marker_pair() -> tuple[MarkerMotion, MarkerMotion]:
    """Two markers over three frames; marker 1 is missing in frame 1 of the original.

    m0: (0,0,0) (2,0,0) (4,0,0), decoded off by (0,1,0) in frame 1 only.
    m1: (0,0,0) gap (0,0,2), decoded (0,0,0) (100,100,100) (0,0,5): the gap's value must not count.
    """
    a = np.array([[[0, 0, 0], [0, 0, 0]], [[2, 0, 0], [NAN, NAN, NAN]], [[4, 0, 0], [0, 0, 2]]], dtype=float)
    b = np.array([[[0, 0, 0], [0, 0, 0]], [[2, 1, 0], [100, 100, 100]], [[4, 0, 0], [0, 0, 5]]], dtype=float)
    orig = MarkerMotion(["m0", "m1"], a, 100.0, units="mm", name="mk")
    return orig, orig.with_positions(b)


# ---------------------------------------------------------------------------------- low-level figures
def test_distortion_by_hand() -> None:
    """A = (0,0,0), (2,0,0): mean (1,0,0), ||A - E(A)|| = sqrt 2; B differs by 1 in one sample."""
    a = np.array([[[0.0, 0, 0]], [[2.0, 0, 0]]])
    b = np.array([[[0.0, 0, 0]], [[2.0, 1, 0]]])
    assert distortion_pct(a, b) == pytest.approx(100 / math.sqrt(2), rel=1e-12)
    assert distortion_pct(a, a) == 0.0


def test_distortion_degenerate() -> None:
    """A static motion has no spread: 0 when decoded exactly, infinite otherwise."""
    a = np.ones((4, 2, 3))
    assert distortion_pct(a, a) == 0.0
    assert distortion_pct(a, a + 1e-3) == float("inf")


def test_distortion_with_gaps_by_hand() -> None:
    """Gaps are out of both the mean and the sums: see _marker_pair (spread 8 + 2, error 1 + 9)."""
    orig, dec = _marker_pair()
    a, b, valid = positions_pair(orig, dec)
    assert valid.tolist() == [[True, True], [True, False], [True, True]]
    assert distortion_pct(a, b, valid) == pytest.approx(100.0, rel=1e-12)


def test_point_errors_and_arms_by_hand() -> None:
    a = np.zeros((2, 2, 3))
    b = np.array([[[3.0, 0, 0], [0, 4, 0]], [[0, 0, 0], [0, 0, 0]]])
    err = point_errors(a, b)
    assert err.tolist() == [[3.0, 4.0], [0.0, 0.0]]
    # frame 0: sqrt((9 + 16) / 2), frame 1: 0
    assert arms(err, np.ones((2, 2), dtype=bool)) == pytest.approx(math.sqrt(12.5) / 2, rel=1e-12)
    # invalid samples leave the per-frame mean: frame 0 is sqrt(9 / 1)
    assert arms(err, np.array([[True, False], [True, True]])) == pytest.approx(1.5, rel=1e-12)
    # a frame without any valid sample is skipped entirely
    assert arms(err, np.array([[True, True], [False, False]])) == pytest.approx(math.sqrt(12.5), rel=1e-12)


def test_bone_len_err_by_hand() -> None:
    a = np.array([[[0.0, 0, 0], [2, 0, 0]], [[0, 0, 0], [0, 4, 0]]])
    b = np.array([[[0.0, 0, 0], [2.5, 0, 0]], [[0, 0, 0], [0, 3, 0]]])
    valid = np.ones((2, 2), dtype=bool)
    pairs = np.array([[1, 0]])
    # frame 0: |2.5 - 2| / 2 = 0.25, frame 1: |3 - 4| / 4 = 0.25 -> max 0.25; and in the other direction
    assert bone_len_err(a, b, valid, pairs) == pytest.approx(0.25, rel=1e-12)
    b[1, 1] = [0, 1, 0]  # 3/4 shorter
    assert bone_len_err(a, b, valid, pairs) == pytest.approx(0.75, rel=1e-12)
    assert bone_len_err(a, a, valid, pairs) == 0.0
    assert bone_len_err(a, b, valid, np.zeros((0, 2), dtype=np.int64)) == 0.0


def test_bone_pairs_of_a_skeleton() -> None:
    orig, _ = _tiny_pair()
    assert bone_pairs(orig).tolist() == [[1, 0], [2, 1]]  # c-r and end-c


def test_bone_pairs_skip_zero_length_bones() -> None:
    m = read_bvh(data_path("cmu/bvh/09_06.bvh"))
    pairs = bone_pairs(m)
    sk = m.skeleton
    # joints whose OFFSET is zero (no bone to measure) are left out
    lengths = np.linalg.norm(np.concatenate([sk.offsets, np.array([o for _, o, _ in sk.end_sites])]), axis=1)
    assert len(pairs) == int((lengths[1:] > 1e-9).sum()) < sk.n_points - 1
    assert all(lengths[p] > 1e-9 for p, _ in pairs)


# ------------------------------------------------------------------------------------- evaluate()
def test_evaluate_skeleton_by_hand() -> None:
    orig, dec = _tiny_pair()
    a, b, valid = positions_pair(orig, dec)
    assert np.allclose(a, [[[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 0, 0], [1, 0, 0], [1, 1, 0]]], atol=1e-15)
    assert np.allclose(b[0], [[0, 0, 0], [2, 0, 0], [3, 0, 0]], atol=1e-15) and valid.all()
    rep = evaluate(orig, dec)
    # spread: only the end site moves, (2,0,0) / (1,1,0) around (1.5,0.5,0): 4 * 0.25 = 1; error: 1 + 1
    assert rep.distortion_pct == pytest.approx(100 * math.sqrt(2), rel=1e-9)
    # frame 0: sqrt((0 + 1 + 1) / 3), frame 1: 0
    assert rep.arms == pytest.approx(math.sqrt(2 / 3) / 2, rel=1e-9)
    assert rep.max_err == pytest.approx(1.0, rel=1e-12)
    assert rep.p99_err == pytest.approx(1.0, rel=1e-12)  # errors 0,0,0,0,1,1
    assert rep.bone_len_err == pytest.approx(1.0, rel=1e-12)  # r-c from 1 to 2
    assert rep.foot_skate is None  # fewer than 3 frames
    assert rep.frames == 2 and rep.points == 3
    assert rep.unit_cm == 2.0 and rep.arms_cm == pytest.approx(2 * rep.arms) and rep.max_err_cm == pytest.approx(2.0)
    d = rep.as_dict()
    assert d["p99_err_cm"] == pytest.approx(2.0) and d["distortion_pct"] == rep.distortion_pct


def test_evaluate_markers_by_hand() -> None:
    orig, dec = _marker_pair()
    rep = evaluate(orig, dec)
    assert rep.distortion_pct == pytest.approx(100.0, rel=1e-12)
    # frame 0: 0; frame 1: only m0 valid, error 1; frame 2: sqrt((0 + 9) / 2)
    assert rep.arms == pytest.approx((0 + 1 + math.sqrt(4.5)) / 3, rel=1e-12)
    assert rep.max_err == pytest.approx(3.0, rel=1e-12)
    # valid errors sorted 0,0,0,1,3: position 0.99 * 4 = 3.96 -> 1 + 0.96 * (3 - 1)
    assert rep.p99_err == pytest.approx(2.92, rel=1e-12)
    # m0-m1 distance: frame 0 zero (left out), frame 1 gap, frame 2 sqrt 20 -> sqrt 41
    assert rep.bone_len_err == pytest.approx(math.sqrt(41 / 20) - 1, rel=1e-12)
    assert rep.unit_cm == 0.1 and rep.max_err_cm == pytest.approx(0.3)
    assert rep.frames == 3 and rep.points == 2


def test_p99_by_hand() -> None:
    """100 errors 0, 1, ..., 99 (two markers, 50 frames): p99 = 98 + 0.01 * (99 - 98) = 98.01."""
    rng = np.random.default_rng(1)
    a = rng.normal(size=(50, 2, 3)) * 10
    err = np.arange(100, dtype=float).reshape(50, 2)
    b = a.copy()
    b[..., 0] += err
    orig = MarkerMotion(["a", "b"], a, 50.0)
    rep = evaluate(orig, orig.with_positions(b))
    assert rep.max_err == pytest.approx(99.0, rel=1e-12)
    assert rep.p99_err == pytest.approx(98.01, rel=1e-12)
    assert rep.arms == pytest.approx(float(np.mean(np.sqrt((err**2).mean(axis=1)))), rel=1e-12)


def test_identical_motions_give_zeros() -> None:
    m = read_bvh(data_path("cmu/bvh/09_06.bvh"))
    rep = evaluate(m, m)
    assert (rep.distortion_pct, rep.arms, rep.max_err, rep.p99_err, rep.bone_len_err) == (0.0, 0.0, 0.0, 0.0, 0.0)
    assert rep.foot_skate in (0.0, None)
    assert rep.points == 38 and rep.frames == 142
    orig, _ = _marker_pair()
    rep = evaluate(orig, orig)
    assert (rep.distortion_pct, rep.arms, rep.max_err, rep.p99_err, rep.bone_len_err) == (0.0, 0.0, 0.0, 0.0, 0.0)


def test_lossless_decoded_clip_gives_zeros() -> None:
    m = read_bvh(data_path("cmu/bvh/09_06.bvh"))
    rep = evaluate(m, decompress(compress(m, codec="lossless")))
    assert rep.distortion_pct == 0.0 and rep.max_err == 0.0 and rep.bone_len_err == 0.0


def test_real_clip_small_perturbation() -> None:
    """A root shift of 1 unit moves every point by exactly 1: arms = max = p99 = 1, bones unchanged."""
    m = read_bvh(data_path("cmu/bvh/09_06.bvh"))
    ch = m.channels.copy()
    ch[:, 1] += 1.0  # Hips Yposition
    rep = evaluate(m, m.with_channels(ch))
    assert rep.arms == pytest.approx(1.0, rel=1e-9)
    assert rep.max_err == pytest.approx(1.0, rel=1e-9) and rep.p99_err == pytest.approx(1.0, rel=1e-9)
    assert rep.bone_len_err < 1e-9
    a = m.positions()
    spread = np.sqrt(((a - a.mean(axis=0)) ** 2).sum())
    assert rep.distortion_pct == pytest.approx(100 * math.sqrt(a.shape[0] * a.shape[1]) / spread, rel=1e-9)
    assert rep.arms_cm == pytest.approx(m.skeleton.unit_cm, rel=1e-9)


def test_decoded_markers_must_keep_samples() -> None:
    orig, dec = _marker_pair()
    pos = dec.positions.copy()
    pos[0, 0] = NAN  # missing in the decoded data, present in the original
    with pytest.raises(MocapzError, match="missing"):
        evaluate(orig, dec.with_positions(pos))


def test_shape_and_kind_mismatch() -> None:
    orig, dec = _tiny_pair()
    with pytest.raises(MocapzError, match="shape"):
        evaluate(orig, orig.slice(0, 1))
    morig, _ = _marker_pair()
    with pytest.raises(MocapzError, match="shape"):
        evaluate(morig, morig.with_positions(morig.positions[:2]))
    with pytest.raises(MocapzError, match="cannot compare"):
        evaluate(orig, morig)


# ------------------------------------------------------------------------------------------- sizes
def test_size_figures_by_hand() -> None:
    orig, _ = _tiny_pair()  # 2 frames x 5 channels -> 40 float32 bytes, 0.2 s
    figs = size_figures(orig, 8, source_bytes=80)
    assert figs == {"raw_bytes": 40, "compressed_bytes": 8, "ratio": 5.0, "ratio_file": 10.0,
                    "bytes_per_second": pytest.approx(40.0)}
    morig, _ = _marker_pair()  # 3 frames x 2 markers x 3 -> 72 bytes
    figs = size_figures(morig, 9)
    assert figs["raw_bytes"] == 72 and figs["ratio"] == 8.0 and figs["ratio_file"] is None


def test_size_figures_real_clip() -> None:
    path = data_path("cmu/bvh/09_06.bvh")
    m = read_bvh(path)
    data = compress(m, codec="lossless")
    figs = size_figures(m, len(data))
    assert figs["raw_bytes"] == 142 * 96 * 4
    assert figs["ratio"] == pytest.approx(figs["raw_bytes"] / len(data), rel=1e-15)
    assert figs["ratio_file"] == pytest.approx(path.stat().st_size / len(data), rel=1e-15)
    assert figs["bytes_per_second"] == pytest.approx(len(data) / (142 / 120), rel=1e-12)


def test_marker_bone_pairs_stay_small_on_hundreds_of_points() -> None:
    """``bone_pairs`` of a marker clip of hundreds of points (a POINT block holding a model's outputs) makes no
    frames x M x M x 3 array (330 points over 500 frames would be 1.3 GB): a few rows at a time, the pairs those of
    the whole computation (each point's most rigid partner: its own copy, shifted)."""
    import tracemalloc
    from dataclasses import replace

    from mocapz.io import load

    m = load(data_path("cmu/c3d/01_01.c3d"))
    base = m.positions[:500]
    pos = np.concatenate([base + np.array([100.0 * k, 0.0, 0.0]) for k in range(8)], axis=1)[:, :330]
    big = replace(m, positions=pos, labels=[f"P{i}" for i in range(330)])
    tracemalloc.start()
    pairs = bone_pairs(big)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 64 << 20, peak
    assert len(pairs) and (pairs[:, 0] < pairs[:, 1]).all()
