"""Pattern codec (Gu, Peng & Deng 2008): every step on hand-made data, then end to end on real clips."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from conftest import data_path

from mocapz.api import compress, decompress
from mocapz.codecs.gaps import decode_mask, encode_mask
from mocapz.codecs.patterns.hierarchy import Hierarchy
from mocapz.codecs.patterns.kmeans import AVE, MAX, adaptive_kmeans, sample_errors
from mocapz.codecs.patterns.marker_tree import build_marker_hierarchy
from mocapz.codecs.patterns.normalise import denormalise, normalise
from mocapz.codecs.patterns.quantise import (
    decode_patterns,
    decode_trajectory,
    encode_patterns,
    encode_trajectory,
)
from mocapz.codecs.patterns.segment import partition
from mocapz.codecs.patterns.segments import decode_segments, encode_segments
from mocapz.errors import FormatError, MocapzError, OptionError
from mocapz.io import load
from mocapz.metrics.figures import evaluate
from mocapz.model.header import ClipHeader
from mocapz.model.motion import MarkerMotion

C3D = "cmu/c3d/01_01.c3d"


@pytest.fixture(scope="module")
def c3d_short() -> MarkerMotion:
    """The first 600 frames (5 s) of CMU 01_01 as markers: 42 labels, mm, with gaps (RBAC-1, RBAC)."""
    m = load(data_path(C3D))
    return m.with_positions(m.positions[:600])


# ------------------------------------------------------------------ Algorithm 1
def _sequence() -> np.ndarray:
    """Two markers: still for 30 frames, then 10 units/frame forward for 30, then back for 21."""
    t = np.arange(81)
    x = np.where(t <= 29, 0.0, np.where(t <= 59, 10.0 * (t - 29), 300.0 - 10.0 * (t - 59)))
    frames = np.zeros((81, 2, 3))
    frames[:, 0, 0] = x
    frames[:, 1, 0] = x
    frames[:, 1, 2] = 50.0
    return frames


def test_algorithm1_known_chopping_points() -> None:
    # frame 30: the still segment's floored mean difference (1/29) is dwarfed by a step of 10 -> cut;
    # then (i - 31) / (89 - i) > 2 first holds at i = 70 after the turn at frame 59 -> cut.
    starts = partition(_sequence(), np.ones((81, 2), bool), np.ones(2), theta=0.01, addh=100.0, ratio=2.0)
    assert starts.tolist() == [0, 30, 70]


def test_algorithm1_ignores_values_in_gaps() -> None:
    frames = _sequence()
    observed = np.ones((81, 2), bool)
    noisy = frames.copy()
    noisy[40:50, 1] += 500.0 * np.random.default_rng(0).standard_normal((10, 3))
    observed[40:50, 1] = False  # garbage only where the marker is missing
    starts = partition(noisy, observed, np.ones(2), theta=0.01, addh=100.0, ratio=2.0)
    assert starts.tolist() == partition(frames, observed, np.ones(2), 0.01, 100.0, 2.0).tolist()
    # the gap's edges (40, 50) end segments; after 50 the turn cuts where (i - 51) / (69 - i) > 2: i = 64
    assert starts.tolist() == [0, 30, 40, 50, 64]
    # without the mask the garbage would create chopping points
    assert len(partition(noisy, np.ones((81, 2), bool), np.ones(2), 0.01, 100.0, 2.0)) > 6


# ------------------------------------------------------------------ normalisation
def test_normalisation_round_trip() -> None:
    rng = np.random.default_rng(1)
    x = np.cumsum(rng.standard_normal((200, 6)), axis=0)
    lengths = np.array([5, 17, 30, 12, 40, 9, 20, 67])
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    length = 20
    y = normalise(x, starts, lengths, length)
    assert y.shape == (8, length, 6)
    back = denormalise(y, np.arange(8), lengths)
    short = np.concatenate([np.arange(s, s + n) for s, n in zip(starts, lengths, strict=True) if n <= length])
    np.testing.assert_allclose(back[short], x[short], atol=1e-9)  # n <= L: exact
    # n > L: the least-squares pattern is at least as close as plain linear resampling
    s, n = 133, 67
    lin = np.linspace(0, n - 1, length)
    plain = np.stack([np.interp(lin, np.arange(n), x[s : s + n, c]) for c in range(6)], axis=1)
    plain_back = denormalise(plain[None], np.array([0]), np.array([n]))
    assert np.abs(back[s : s + n] - x[s : s + n]).sum() <= np.abs(plain_back - x[s : s + n]).sum() + 1e-9


# ------------------------------------------------------------------ adaptive K-means
def test_adaptive_kmeans_meets_max_error_bound() -> None:
    rng = np.random.default_rng(2)
    centres = rng.uniform(-50, 50, (6, 30))
    x = np.concatenate([c + rng.normal(0, 1.0, (80, 30)) for c in centres] + [rng.uniform(-80, 80, (5, 30))])
    o = np.ones_like(x)
    tol = 2.0
    cl = adaptive_kmeans(x, o, tol, k0=2, metric=MAX)
    err = sample_errors(x, o, cl.centers[cl.labels], per_member=3)
    assert err.max() <= tol + 1e-9
    assert len(cl.centers) >= 6 + 1  # grew from 2: the blobs and (some of) the outliers
    np.testing.assert_allclose(err, cl.errors, atol=1e-5)
    ave = adaptive_kmeans(x, o, tol, k0=2, metric=AVE)
    assert (ave.errors**2).mean() <= tol**2 + 1e-9
    assert len(ave.centers) <= len(cl.centers)


def test_masked_values_never_disturb_clustering() -> None:
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.normal(0, 1, (50, 12)), rng.normal(20, 1, (50, 12))])
    o = np.ones_like(x)
    o[::7, :3] = 0.0
    garbage = x.copy()
    garbage[o == 0] = 1e6
    a = adaptive_kmeans(x, o, 3.0, k0=2)
    b = adaptive_kmeans(garbage, o, 3.0, k0=2)
    assert np.array_equal(a.labels, b.labels)
    np.testing.assert_allclose(a.centers[:, 3:], b.centers[:, 3:])


# ------------------------------------------------------------------ coding
def test_pattern_database_round_trip_is_bit_exact() -> None:
    rng = np.random.default_rng(4)
    patterns = np.cumsum(rng.normal(0, 3, (25, 14, 9)), axis=1) + rng.normal(0, 100, (25, 1, 9))
    data, rec = encode_patterns(patterns, step=1.7, sigma=0.7)
    back, used = decode_patterns(data)
    assert used == len(data)
    assert np.array_equal(back, rec)
    raw, _ = encode_patterns(patterns, step=1.7)
    unsmoothed, _ = decode_patterns(raw)
    assert np.abs(unsmoothed - patterns).max() <= 1.7 / 2 + 1e-9  # every value within half a step


def test_trajectory_segments_and_mask_round_trip() -> None:
    rng = np.random.default_rng(5)
    root = np.cumsum(np.cumsum(rng.normal(0, 0.3, (500, 4)), axis=0), axis=0)
    data, rec = encode_trajectory(root, np.array([0.5, 0.5, 0.5, 0.01]))
    back, _ = decode_trajectory(data)
    assert np.array_equal(back, rec)
    assert np.abs(rec - root).max() <= 0.5 / 2 + 1e-9
    labels = np.array([0, 1, 0, 2, 1, 3, 3, 0, 4, 2])
    lengths = np.array([12, 7, 13, 30, 7, 1, 2, 12, 44, 30])
    assert [a.tolist() for a in decode_segments(encode_segments(labels, lengths, 5), 5)] == \
        [labels.tolist(), lengths.tolist()]
    prior = np.array([9, 3, 0, 4, 1])
    back = decode_segments(encode_segments(labels[::-1], lengths, 5, prior), 5, prior)
    assert back[0].tolist() == labels[::-1].tolist()
    missing = rng.random((300, 7)) < 0.05
    missing[:20, 3] = True
    assert np.array_equal(decode_mask(encode_mask(missing), 300, 7), missing)


# ------------------------------------------------------------------ hierarchy
def test_standard_marker_hierarchy(c3d_short: MarkerMotion) -> None:
    h = build_marker_hierarchy(c3d_short.labels, c3d_short.positions)
    lab = c3d_short.labels
    assert lab[h.nodes[0].reference] == "C7" and h.nodes[0].members == [lab.index("C7")]
    by_name = {n.name: n for n in h.nodes}
    assert {lab[i] for i in by_name["head"].members} == {"LFHD", "RFHD", "LBHD", "RBHD"}
    assert h.nodes[by_name["lforearm"].parent].name == "larm"
    assert sorted(i for n in h.nodes for i in n.members) == list(range(len(lab)))  # RBAC-1 attached too
    assert Hierarchy.from_bytes(h.to_bytes(with_names=True)).signature() == h.signature()


# ------------------------------------------------------------------ end to end
def test_markers_round_trip_keeps_gaps_and_is_deterministic(c3d_short: MarkerMotion) -> None:
    loose = {"max_error": "1m", "hold_feet": False}  # the model's own errors (the default target corrects them)
    a = compress(c3d_short, codec="patterns", bits=3, tolerance=0.05, **loose)
    assert a == compress(c3d_short, codec="patterns", bits=3, tolerance=0.05, **loose)
    dec = decompress(a)
    assert dec.labels == c3d_short.labels
    assert np.array_equal(dec.missing, c3d_short.missing) and c3d_short.missing.any()
    rep = evaluate(c3d_short, dec)
    assert rep.arms < 8.0  # mm
    assert c3d_short.raw_bytes / len(a) > 15


def test_max_arms_target_is_met(c3d_short: MarkerMotion) -> None:
    data = compress(c3d_short, codec="patterns", max_arms="6.5mm", bits=3)
    rep = evaluate(c3d_short, decompress(data))
    assert 4.0 < rep.arms <= 6.5
    tight = compress(c3d_short, codec="patterns", max_arms="3mm", bits=3)
    assert evaluate(c3d_short, decompress(tight)).arms <= 3.0
    assert len(tight) > len(data)


def test_heavier_marker_is_reconstructed_more_accurately(c3d_short: MarkerMotion) -> None:
    i = c3d_short.labels.index("LSHO")

    def marker_rms(weight: float) -> float:
        d = decompress(compress(c3d_short, codec="patterns", bits=3, tolerance=0.05, weights={"LSHO": weight},
                                max_error="1m", hold_feet=False))  # a loose target: the model's errors
        return float(np.sqrt(np.nanmean(np.sum((d.positions[:, i] - c3d_short.positions[:, i]) ** 2, axis=1))))

    heavy, even, light = marker_rms(10.0), marker_rms(1.0), marker_rms(0.1)
    assert heavy < 0.8 * even and heavy < 0.8 * light


def test_bvh_comes_back_with_its_skeleton() -> None:
    m = load(data_path("cmu/bvh/09_06.bvh"))
    data = compress(m, codec="patterns", max_distortion=1.0)
    dec = decompress(data)
    assert dec.skeleton.names == m.skeleton.names
    np.testing.assert_array_equal(dec.skeleton.offsets, m.skeleton.offsets)
    assert dec.skeleton.channels == m.skeleton.channels
    rep = evaluate(m, dec)
    assert rep.distortion_pct <= 1.0
    assert m.raw_bytes / len(data) > 10


def test_asf_amc_round_trip() -> None:
    m = load(data_path("cmu/asfamc/01_01.amc"))
    m = m.slice(0, 500)
    dec = decompress(compress(m, codec="patterns", bits=3, tolerance=0.04))
    assert dec.channels.shape == m.channels.shape
    assert evaluate(m, dec).arms_cm < 1.0


# ------------------------------------------------------------------ bad input
def test_unknown_label_in_weights_file(tmp_path, c3d_short: MarkerMotion) -> None:
    f = tmp_path / "w.json"
    f.write_text(json.dumps({"LFHD": 2, "NOSE": 3}))
    with pytest.raises(OptionError, match=r"w\.json.*NOSE"):
        compress(c3d_short, codec="patterns", weights=str(f))
    with pytest.raises(OptionError, match="NOSE"):
        compress(c3d_short, codec="patterns", weights="NOSE=2")
    f.write_text("{not json")
    with pytest.raises(OptionError, match="w.json"):
        compress(c3d_short, codec="patterns", weights=str(f))


@pytest.mark.parametrize("text, problem", [
    ("{nodes: [", "not valid JSON"),
    ('{"nodes": []}', "non-empty"),
    ('{"nodes": [{"name": "a", "markers": ["C7"]}, {"name": "b", "markers": ["LFHD"]}]}', "exactly one node"),
    ('{"nodes": [{"name": "r", "markers": ["C7"]}, {"name": "h", "parent": "x", "markers": ["LFHD"]}]}',
     "unknown parent"),
    ('{"nodes": [{"name": "r", "markers": ["C7"]}, {"name": "h", "parent": "r", "markers": ["NOSE"]}]}',
     "unknown member 'NOSE'"),
    ('{"nodes": [{"name": "r", "markers": ["C7"]}, {"name": "h", "parent": "r", "markers": ["C7"]}]}',
     "more than one node"),
])
def test_malformed_hierarchy_json(tmp_path, c3d_short: MarkerMotion, text: str, problem: str) -> None:
    f = tmp_path / "h.json"
    f.write_text(text)
    with pytest.raises(OptionError, match=problem) as err:
        compress(c3d_short, codec="patterns", hierarchy=str(f))
    assert "h.json" in str(err.value)


def test_explicit_hierarchy_json(tmp_path, c3d_short: MarkerMotion) -> None:
    f = tmp_path / "h.json"
    f.write_text(json.dumps({"nodes": [
        {"name": "root", "markers": ["C7"]},
        {"name": "head", "parent": "root", "markers": ["LFHD", "RFHD", "LBHD", "RBHD"]},
        {"name": "larm", "parent": "root", "markers": ["LSHO", "LUPA", "LELB"], "reference": "LELB"},
        {"name": "lhand", "parent": "larm", "markers": ["LWRA", "LWRB", "LFIN", "LFRM"]},
    ]}))
    dec = decompress(compress(c3d_short, codec="patterns", hierarchy=str(f), bits=3, tolerance=0.05))
    assert evaluate(c3d_short, dec).arms < 10.0  # unlisted markers were attached automatically


def test_zero_markers_and_bad_options(c3d_short: MarkerMotion) -> None:
    empty = MarkerMotion(labels=[], positions=np.zeros((10, 0, 3)), frame_rate=120.0, name="empty")
    with pytest.raises(FormatError, match="no markers"):
        compress(empty, codec="patterns")
    with pytest.raises(OptionError, match="has no option quality"):
        compress(c3d_short, codec="patterns", quality=3)
    with pytest.raises(OptionError, match="bits"):
        compress(c3d_short, codec="patterns", bits=0)
    with pytest.raises(OptionError, match="max_arms"):
        compress(c3d_short, codec="patterns", max_arms="6.5 parsecs")
    with pytest.raises(MocapzError):
        decompress(compress(c3d_short, codec="patterns", bits=3, tolerance=0.05)[:-9])


def test_corrupted_stream_is_a_format_error(c3d_short: MarkerMotion) -> None:
    from mocapz.codecs.patterns import decode
    from mocapz.format.container import Container

    box = Container.from_bytes(compress(c3d_short, codec="patterns", bits=3, tolerance=0.05))
    sections = dict(box.sections)
    sections["s3"] = sections["s3"][:5]
    with pytest.raises(FormatError):
        decode(sections, ClipHeader.of(c3d_short))


def test_marker_pair_statistics_stay_small_on_hundreds_of_points() -> None:
    """A C3D whose POINT block holds a model's outputs beside the markers can carry hundreds of points: the
    hierarchy's pairwise rigidity is computed a few rows at a time (no frames x M x M x 3 array: 330 points over
    400 frames would be 1 GB), each pair's figures those of its two trajectories alone."""
    import tracemalloc

    from mocapz.codecs.patterns.marker_tree import _stats

    base = load(data_path("cmu/c3d/01_01.c3d")).positions[:400]
    rng = np.random.default_rng(0)
    pos = np.concatenate([base + rng.normal(0.0, 20.0, 3) for _ in range(8)], axis=1)[:, :330]  # 330 points
    tracemalloc.start()
    rig, mean, cnt = _stats(pos)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 64 << 20, peak
    for i, j in [(0, 1), (5, 200), (329, 17), (100, 100)]:
        d = np.linalg.norm(pos[:, i] - pos[:, j], axis=1)
        ok = np.isfinite(d)
        assert cnt[i, j] == ok.sum()
        assert mean[i, j] == pytest.approx(d[ok].mean() if ok.any() else 0.0, abs=1e-9)
        assert rig[i, j] == pytest.approx(d[ok].std() if ok.any() else 0.0, abs=1e-6)


def test_points_rigid_to_the_bit_are_grouped_without_end() -> None:
    """Points that keep their distances exactly (a model's virtual points computed on a segment's markers, stored
    in the POINT block) cannot be split by a rigidity cut: the hierarchy splits such a group in order instead of
    halving its cut for ever (a RecursionError before), and the patterns codec meets its target on the clip."""
    m = load(data_path("cmu/c3d/01_01.c3d"))
    pos = np.concatenate([m.positions[:300] + np.array([100.0 * k, 0.0, 0.0]) for k in range(8)], axis=1)
    big = replace(m, positions=pos, labels=[f"P{i}" for i in range(pos.shape[1])])
    hier = build_marker_hierarchy(big.labels, big.positions)
    assert sorted(i for n in hier.nodes for i in n.members) == list(range(pos.shape[1]))
    data = compress(big, "patterns", max_error="1cm")
    assert evaluate(big, decompress(data)).max_err <= 1.0 / m.unit_cm * (1 + 1e-6)
