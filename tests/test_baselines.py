"""Baseline codecs (subsample, pca, segpca, quant) on real CMU data: exactness at their lossless settings,
the quant codec's per-track error threshold, gaps kept in marker data, determinism, bad options."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace
from functools import cache

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz import FormatError, MarkerMotion, Motion, OptionError
from mocapz.codecs import codec_names, get_codec
from mocapz.codecs.baselines import pca, quant, segpca, subsample
from mocapz.codecs.baselines.common import values_of
from mocapz.format.container import Container
from mocapz.format.layout import decode_header
from mocapz.model.header import ClipHeader

BASELINES = ("subsample", "pca", "segpca", "quant")
BVH = "cmu/bvh/09_06.bvh"  # 142 frames, 96 channels, T-pose in frame 1
AMC = "cmu/asfamc/backflip.amc"  # 247 frames, float64 values (no fixed decimals)
C3D = "cmu/c3d/01_01.c3d"  # 42 markers, mm, 2.4 % missing


@pytest.fixture(autouse=True)
def _one_thread() -> Iterator[None]:
    """SVDs on one BLAS thread (shared 2-core machines crawl with oversubscribed BLAS pools)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield


@cache
def _load(rel: str) -> Motion | MarkerMotion:
    return mocapz.load(data_path(rel))


@cache
def _markers() -> MarkerMotion:
    """A 600-frame window of the CMU C3D that holds gaps (the whole clip is 2751 frames)."""
    m = _load(C3D)
    assert isinstance(m, MarkerMotion)
    gappy = np.flatnonzero(m.missing.any(axis=1))
    start = int(max(0, gappy[0] - 100))
    cut = replace(m, positions=m.positions[start : start + 600].copy())
    assert cut.missing.any() and not cut.missing.all()
    return cut


def _roundtrip(motion: Motion | MarkerMotion, codec: str, **options: object) -> Motion | MarkerMotion:
    return mocapz.decompress(mocapz.compress(motion, codec=codec, **options))


def _model_roundtrip(motion: Motion | MarkerMotion, **options: object) -> Motion | MarkerMotion:
    """The quant model alone (its own encoder and decoder, without the correction layer the codec adds)."""
    checked = get_codec("quant").validate(options)
    return quant.decode(quant.encode(motion, **checked), ClipHeader.of(motion))


def _angle_diff(a: np.ndarray, b: np.ndarray, period: float = 360.0) -> np.ndarray:
    """|a - b| modulo a full turn."""
    d = np.mod(a - b + period / 2, period) - period / 2
    return np.abs(d)


def test_registered() -> None:
    for name in BASELINES:
        assert name in codec_names()
        info = get_codec(name)
        assert info.name == name and set(info.kinds) == {"skeleton", "markers"}


# ---------------------------------------------------------------- exact settings
@pytest.mark.parametrize("rel", [BVH, AMC])
@pytest.mark.parametrize(("codec", "options"), [("subsample", {"factor": 1}), ("pca", {"variance": 1.0})])
def test_exact_settings_skeleton(rel: str, codec: str, options: dict[str, object]) -> None:
    """Subsampling by 1 and PCA with every component give the channels back up to float32 precision."""
    m = _load(rel)
    assert isinstance(m, Motion)
    back = _roundtrip(m, codec, **options)
    assert isinstance(back, Motion)
    assert back.skeleton.channel_labels() == m.skeleton.channel_labels()
    rot = m.skeleton.rotation_columns()
    scale = np.abs(values_of(m).x).max(axis=0)  # unwrapped magnitudes bound the float32 error
    tol = 4 * np.finfo(np.float32).eps * np.maximum(scale, 1.0) + 1e-4
    assert np.all(_angle_diff(back.channels[:, rot], m.channels[:, rot]) <= tol[rot])
    assert np.all(np.abs(back.channels[:, ~rot] - m.channels[:, ~rot]) <= tol[~rot])
    rep = mocapz.evaluate(m, back)
    assert rep.max_err_cm is not None and rep.max_err_cm < 0.01
    if m.decimals is not None:  # rounded back to the file's precision: bit-exact
        assert np.array_equal(np.where(rot, np.mod(back.channels + 180, 360) - 180, back.channels),
                              np.where(rot, np.mod(m.channels + 180, 360) - 180, m.channels))


@pytest.mark.parametrize(("codec", "options"), [("subsample", {"factor": 1}), ("pca", {"variance": 1.0})])
def test_exact_settings_markers(codec: str, options: dict[str, object]) -> None:
    m = _markers()
    back = _roundtrip(m, codec, **options)
    assert isinstance(back, MarkerMotion)
    ok = ~m.missing
    err = np.abs(back.positions[ok] - m.positions[ok])
    assert err.max() <= 4 * np.finfo(np.float32).eps * np.nanmax(np.abs(m.positions)) + 1e-6


def test_decoded_angles_wrapped() -> None:
    """Rotation channels come back in [-180, 180) degrees whatever the unwrapping did."""
    m = _load(BVH)
    rot = m.skeleton.rotation_columns()
    for codec in BASELINES:
        back = _roundtrip(m, codec)
        assert back.channels[:, rot].min() >= -180 and back.channels[:, rot].max() < 180, codec


# ---------------------------------------------------------------- quant: error threshold per track
@pytest.mark.parametrize("rel", [BVH, AMC])
@pytest.mark.parametrize("max_error", ["0.1cm", "1cm", "5cm"])
def test_quant_meets_threshold_per_track(rel: str, max_error: str) -> None:
    m = _load(rel)
    assert isinstance(m, Motion)
    unit_cm = m.skeleton.unit_cm
    assert unit_cm
    limit = float(max_error[:-2]) / unit_cm
    tol = quant.tolerances(m, limit)
    back = _model_roundtrip(m, max_error=max_error)
    rot = m.skeleton.rotation_columns()
    diff = np.where(rot, _angle_diff(back.channels, m.channels), np.abs(back.channels - m.channels))
    per_track = diff.max(axis=0)
    finite = np.isfinite(tol)
    assert np.all(per_track[finite] <= tol[finite] * (1 + 1e-9) + 1e-9)
    rep = mocapz.evaluate(m, back)
    assert rep.max_err <= limit
    assert rep.max_err > limit / 50  # the budget is used, not wasted on a needlessly fine step


def test_quant_tolerance_budget_adds_up() -> None:
    """On every point, the worst-case displacements of the tracks moving it sum to at most max_error."""
    m = _load(BVH)
    assert isinstance(m, Motion)
    sk = m.skeleton
    tol = quant.skeleton_tolerances(sk, m.channels, 1.0)
    assert np.all(tol > 0)
    rot = sk.rotation_columns()
    assert np.all(np.isfinite(tol[~rot]))  # every position channel moves the body


def test_quant_markers_threshold_and_gaps() -> None:
    m = _markers()
    back = _model_roundtrip(m, max_error="2mm")
    ok = ~m.missing
    assert np.array_equal(back.missing, m.missing)
    per_coord = np.abs(back.positions - m.positions)[ok]
    assert per_coord.max() <= 2.0 / math.sqrt(3)
    assert mocapz.evaluate(m, back).max_err <= 2.0


def test_quant_bits_follow_threshold() -> None:
    """A tenfold finer threshold costs about log2(10) = 3.3 more bits on the moving tracks."""
    m = _load(BVH)
    info = get_codec("quant")  # the quant model alone (the codec adds its correction layer)
    box = {e: quant.encode(m, **info.validate({"max_error": e})) for e in ("1cm", "0.1cm")}
    coarse, fine = (quant.track_bits(box[e]) for e in ("1cm", "0.1cm"))
    moving = coarse > 0
    assert np.all(fine >= coarse)
    assert 2.5 < float(np.mean(fine[moving] - coarse[moving])) < 4.5


# ---------------------------------------------------------------- gaps, determinism, quality order
@pytest.mark.parametrize("codec", BASELINES)
def test_marker_gaps_kept(codec: str) -> None:
    m = _markers()
    back = _roundtrip(m, codec)
    assert back.positions.shape == m.positions.shape
    assert np.array_equal(np.isnan(back.positions), np.isnan(m.positions))
    assert np.isfinite(mocapz.evaluate(m, back).max_err)


@pytest.mark.parametrize("codec", BASELINES)
@pytest.mark.parametrize("rel", [BVH, AMC])
def test_deterministic_bytes(codec: str, rel: str) -> None:
    m = _load(rel)
    assert mocapz.compress(m, codec=codec) == mocapz.compress(m, codec=codec)


@pytest.mark.parametrize(("codec", "key", "values"), [
    ("subsample", "factor", (2, 4, 8)),
    ("pca", "variance", (0.9999, 0.999, 0.99)),
    ("segpca", "variance", (0.9999, 0.999, 0.99)),
    ("quant", "max_error", ("0.3cm", "1cm", "3cm")),
])
def test_rate_distortion_order(codec: str, key: str, values: tuple[object, ...]) -> None:
    """Coarser settings give smaller models and larger errors (on a real walk clip, T-pose cut off; the models
    alone: the codecs add a correction layer that meets their target whatever the setting)."""
    m = _load("cmu/bvh/02_01.bvh").slice(1)
    module = {"subsample": subsample, "pca": pca, "segpca": segpca, "quant": quant}[codec]
    sizes, errors = [], []
    for v in values:
        sections = module.encode(m, **get_codec(codec).validate({key: v}))
        sizes.append(sum(len(b) for b in sections.values()))
        errors.append(mocapz.evaluate(m, module.decode(sections, ClipHeader.of(m))).distortion_pct)
    assert sizes == sorted(sizes, reverse=True)
    assert errors == sorted(errors)


def test_subsample_key_frames_and_size() -> None:
    m = _load(BVH)
    assert subsample.key_frames(10, 4).tolist() == [0, 4, 8, 9]
    assert subsample.key_frames(9, 4).tolist() == [0, 4, 8]
    data = mocapz.compress(m, codec="subsample", factor=4)
    keys = len(subsample.key_frames(m.n_frames, 4))
    assert len(Container.from_bytes(data).sections["keys"]) == keys * m.skeleton.n_channels * 4  # float32


def test_segpca_segments_cover_clip() -> None:
    m = _load("cmu/bvh/02_01.bvh")
    v = values_of(m)
    lengths = segpca.segment(v.x, 0.99, 6, 15, 480)
    assert sum(lengths) == m.n_frames and all(n >= 1 for n in lengths) and max(lengths) <= 480
    box = Container.from_bytes(mocapz.compress(m, codec="segpca", variance=0.99, components=6, max_segment=480))
    assert mocapz.decompress(box.to_bytes()).n_frames == decode_header(box.layout).frames


# ---------------------------------------------------------------- errors
@pytest.mark.parametrize(("codec", "options"), [
    ("subsample", {"factor": 0}),
    ("subsample", {"factor": 2.5}),
    ("subsample", {"bogus": 1}),
    ("pca", {"variance": 0}),
    ("pca", {"variance": 1.5}),
    ("pca", {"components": 0}),
    ("segpca", {"key": 0}),
    ("segpca", {"components": 1000}),
    ("quant", {"max_error": "-1cm"}),
    ("quant", {"max_error": "fast"}),
    ("quant", {"max_error": 0}),
])
def test_bad_options(codec: str, options: dict[str, object]) -> None:
    with pytest.raises(OptionError):
        mocapz.compress(_load(BVH), codec=codec, **options)


@pytest.mark.parametrize("codec", BASELINES)
def test_corrupted_sections(codec: str) -> None:
    m = _load(BVH)
    box = Container.from_bytes(mocapz.compress(m, codec=codec))
    header = decode_header(box.layout)
    info = get_codec(codec)
    for name in box.sections:
        broken = dict(box.sections)
        broken[name] = broken[name][: len(broken[name]) // 2]
        try:
            info.decode(broken, header)
        except FormatError:
            continue
        except (ValueError, IndexError, KeyError, TypeError):
            continue  # the API turns these into FormatError (see mocapz.api.decompress)
    missing = dict(box.sections)
    missing.pop(next(iter(missing)))
    with pytest.raises(FormatError):
        info.decode(missing, header)
