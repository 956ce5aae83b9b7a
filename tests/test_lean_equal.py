"""The encoder's lean structures and chunked figures (issue 12: peak memory) give, to the bit, what the dense
whole-clip computations they replace gave, on real clips: the per-column tolerances, the closed loop fed
with them, the figures computed a thousand frames at a time, the range coder fed a chunk at a time and the
zstd byte planes made a few columns at a time. Each reference below is the code that was replaced."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.codecs.correction import bounds, context
from mocapz.codecs.correction.fit import Clip
from mocapz.format import entropy
from mocapz.metrics import figures
from mocapz.model.motion import MarkerMotion, Motion


@pytest.fixture(scope="module")
def walk() -> Motion:
    m = mocapz.load(data_path("cmu/bvh/06_13.bvh"))  # 4,906 frames: several chunks of every kind
    assert isinstance(m, Motion)
    return m


@pytest.fixture(scope="module")
def markers() -> MarkerMotion:
    m = mocapz.load(data_path("cmu/c3d/01_01.c3d"))  # gaps (NaN) in 2.4 % of the samples
    assert isinstance(m, MarkerMotion) and m.missing.any()
    return m


def _dense_tolerances(t0: np.ndarray, lay: bounds.Layout, levels: np.ndarray) -> np.ndarray:
    return t0[None, :] * 2.0 ** (-levels[:, lay.group].astype(np.float64) / 2.0)


def _levels(clip: Clip, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Base tolerances at 1 cm and levels as a fit leaves them: the safe levels, relaxed, some tightened."""
    lay, rng = clip.layout, np.random.default_rng(seed)
    e = 1.0 / clip.motion.unit_cm if clip.motion.unit_cm else clip.body / 170.0
    t0 = bounds.tol_of(bounds.code_for(np.where(lay.moving, 16 * lay.t_safe * e, bounds.TINY * lay.t_safe * e)))
    levels = np.maximum(bounds.safe_levels(lay, clip.point_bounds(e), e, 16.0) - 8, 0)
    levels += rng.integers(0, 2, size=levels.shape) * (rng.random(levels.shape) < 0.05)
    return t0, levels


def test_column_tolerances_are_the_dense_array(walk: Motion, markers: MarkerMotion) -> None:
    for motion in (walk, markers):
        clip = Clip(motion, True)
        t0, levels = _levels(clip, 1)
        dense = _dense_tolerances(t0, clip.layout, levels)
        tol = bounds.tolerances(t0, clip.layout, levels)
        assert tol.shape == dense.shape
        assert np.array_equal(np.asarray(tol), dense)
        for cols in np.array_split(np.arange(dense.shape[1]), 17):  # a joint's or marker's columns at a time
            assert np.array_equal(tol[:, cols], dense[:, cols])
        levels[::7] += 1  # a reference: the levels as they are when the columns are asked for
        assert np.array_equal(np.asarray(tol), _dense_tolerances(t0, clip.layout, levels))


def test_closed_loop_per_column_gives_the_dense_coding(walk: Motion) -> None:
    """The loop fed per-column tolerances codes what it codes with the dense array, its feedback goals written
    into the residual's own columns (the others left as they were)."""
    clip = Clip(walk.slice(0, 1500), True)
    assert clip.chain is not None
    t0, levels = _levels(clip, 2)
    base = np.zeros_like(clip.values)
    plain = clip.residual(base)
    coded = []
    for tol in (_dense_tolerances(t0, clip.layout, levels), bounds.tolerances(t0, clip.layout, levels)):
        clip.chain.forget()
        x = clip.residual(base)
        coded.append([a.copy() for a in clip.chain.quantise(x, base, tol, 4, 0.85)] + [x])
    for a, b in zip(coded[0], coded[1], strict=True):
        assert np.array_equal(a, b)
    fb = np.concatenate([c for c, f in zip(clip.chain.rot_cols, clip.chain.feedback, strict=True) if f])
    others = np.setdiff1d(np.arange(plain.shape[1]), fb)
    assert np.array_equal(coded[1][3][:, others], plain[:, others])
    assert not np.array_equal(coded[1][3][:, fb], plain[:, fb])


def _decoded(motion: Motion | MarkerMotion) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Original and decoded (quant at 1 cm) positions and the present samples (None: all)."""
    a, b, valid = figures.positions_pair(motion, mocapz.decompress(mocapz.compress(motion, "quant")))
    return a, b, (None if valid.all() else valid)


def _distortion_before(a: np.ndarray, b: np.ndarray, valid: np.ndarray | None = None) -> float:
    if valid is None:
        valid = np.ones(a.shape[:2], dtype=bool)
    w = valid[..., None]
    a0 = np.where(w, a, 0.0)
    b0 = np.where(w, b, 0.0)
    counts = np.maximum(valid.sum(axis=0), 1)[:, None]
    mean = a0.sum(axis=0) / counts
    den = np.sqrt((np.where(w, a0 - mean, 0.0) ** 2).sum())
    num = np.sqrt(((a0 - b0) ** 2).sum())
    return float(100.0 * num / den) if den > 0 else (0.0 if num == 0 else float("inf"))


def test_chunked_figures_are_the_whole_clip_figures(walk: Motion, markers: MarkerMotion) -> None:
    for motion in (walk.slice(0, 2600), markers):
        a, b, valid = _decoded(motion)
        assert a.shape[0] > figures.CHUNK_FRAMES
        with np.errstate(invalid="ignore"):
            assert np.array_equal(figures.point_errors(a, b), np.linalg.norm(a - b, axis=-1), equal_nan=True)
            assert np.array_equal(figures.point_errors(b, a), np.linalg.norm(b - a, axis=-1), equal_nan=True)
        assert figures.distortion_pct(a, b, valid) == _distortion_before(a, b, valid)
        if valid is not None:  # markers: also as if every sample were present (NaN-free copies)
            a1, b1 = np.nan_to_num(a), np.nan_to_num(b)
            assert figures.distortion_pct(a1, b1) == _distortion_before(a1, b1)
            assert figures.distortion_pct(a1, b1, np.ones(a.shape[:2], bool)) == _distortion_before(a1, b1)
            for f1, g1 in ((np.asfortranarray(a1), b1), (a1, np.asfortranarray(b1))):  # not C-ordered: copies
                assert figures.distortion_pct(f1, g1) == _distortion_before(f1, g1)
        for p in (a, b):
            before = (np.diff(np.nan_to_num(p), 2, axis=0) ** 2).sum(axis=2)
            assert np.array_equal(context.squared_accelerations(p), before)


def _jitter_before(a: np.ndarray, b: np.ndarray, valid: np.ndarray) -> float | None:
    def energy(p: np.ndarray, ok: np.ndarray) -> float:
        acc = p[2:] - 2.0 * p[1:-1] + p[:-2]
        return float(np.where(ok, np.sum(acc * acc, axis=-1), 0.0).sum())

    ok = valid[2:] & valid[1:-1] & valid[:-2]
    ea, eb = energy(np.where(valid[..., None], a, 0.0), ok), energy(np.where(valid[..., None], b, 0.0), ok)
    return (0.0 if eb == 0.0 else float("inf")) if ea == 0.0 else 100.0 * (eb / ea - 1.0)


def _bone_before(a: np.ndarray, b: np.ndarray, valid: np.ndarray, pairs: np.ndarray) -> float:
    la = np.linalg.norm(a[:, pairs[:, 0]] - a[:, pairs[:, 1]], axis=-1)
    lb = np.linalg.norm(b[:, pairs[:, 0]] - b[:, pairs[:, 1]], axis=-1)
    ok = valid[:, pairs[:, 0]] & valid[:, pairs[:, 1]] & (la > 1e-9)
    return float(np.max(np.abs(lb - la)[ok] / la[ok])) if ok.any() else 0.0


def _up_before(a: np.ndarray, valid: np.ndarray) -> int:
    big = np.where(valid[..., None], a, np.nan)
    with np.errstate(invalid="ignore"):
        ext = np.nanmax(big, axis=1) - np.nanmin(big, axis=1)
    return int(np.argmax(np.nanmedian(ext, axis=0)))


def test_chunked_jitter_bones_and_up_axis_are_the_whole_clip_ones(walk: Motion, markers: MarkerMotion) -> None:
    """The verification's jitter, bone length error and vertical axis (and so its contacts), a chunk of frames at
    a time: the numbers of the whole clip's arrays, on a skeleton (bone lengths moved by a stretched leg) and on
    markers with gaps (their bones: none; their up axis from every present sample)."""
    from mocapz.metrics import contacts, skate

    for motion in (walk.slice(0, 2600), markers):
        a, b, valid = _decoded(motion)
        valid = np.ones(a.shape[:2], dtype=bool) if valid is None else valid
        assert a.shape[0] > figures.CHUNK_FRAMES
        if isinstance(motion, Motion):  # one bone longer in some frames: a bone length error the chunks must find
            b = b.copy()
            b[1500:1510, 3] += 2.0
        got, want = skate.jitter_pct(a, b, valid), _jitter_before(a, b, valid)
        assert got == want and got is not None and got != 0
        pairs = figures.bone_pairs(motion)
        assert figures.bone_len_err(a, b, valid, pairs) == _bone_before(a, b, valid, pairs)
        assert figures.bone_len_err(a, b, valid, pairs) > (0.01 if len(pairs) else -1)
        body = motion.skeleton.body_points() if isinstance(motion, Motion) else np.arange(a.shape[1])
        assert contacts.up_axis(a, valid, body) == _up_before(a[:, body], valid[:, body])
        assert contacts.up_axis(a, valid) == _up_before(a, valid)


@pytest.fixture(scope="module")
def integers(walk: Motion) -> np.ndarray:
    """The integers of a real correction (the closed loop on a zero base at 1 cm, the whole clip)."""
    clip = Clip(walk, True)
    t0, levels = _levels(clip, 3)
    base = np.zeros_like(clip.values)
    return clip.quantise(clip.residual(base), base, bounds.tolerances(t0, clip.layout, levels), 5)[0]


def test_range_coder_in_chunks_writes_the_one_call_stream(integers: np.ndarray,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    q = integers
    assert q.size > 4 * entropy.CHUNK_VALUES
    parts = [q, q[1:], q[::3], q[:, :5], np.clip(q * 40000, -2**40, 2**40)]  # the last one with escapes
    chunked = [[entropy.encode_int_matrix(p, c) for c in (None, entropy.CODER_RANGE, entropy.CODER_RANGE_DELTA)]
               for p in parts]
    monkeypatch.setattr(entropy, "CHUNK_VALUES", 1 << 40)  # one call of the coder for all the values
    whole = [[entropy.encode_int_matrix(p, c) for c in (None, entropy.CODER_RANGE, entropy.CODER_RANGE_DELTA)]
             for p in parts]
    assert chunked == whole
    for p, streams in zip(parts, chunked, strict=True):
        assert all(np.array_equal(entropy.decode_int_matrix(s), p) for s in streams)


def test_byte_planes_by_columns_are_the_whole_matrix_planes(integers: np.ndarray) -> None:
    q = integers
    for p in (q, q[:, :1], q[:0], q * 300, q.T):
        assert entropy.pack_zigzag_columns(p) == entropy.pack_uint64(entropy.zigzag(p.T))
        v = np.asarray(p, dtype=np.int64)
        assert np.array_equal(entropy.zigzag(v), ((v << 1) ^ (v >> 63)).astype(np.uint64))


def test_byte_planes_unpack_in_narrow_types_to_the_wide_values(integers: np.ndarray) -> None:
    """Every byte width (1 to 8), the extremes of each, the real integers: the narrow-type unpacker gives the
    values and the memory order of the uint64 one (and the zstd stream decodes to the matrix coded)."""
    q = integers
    rng = np.random.default_rng(5)
    cases = [q, q[:, :1], q.T, q * 300, np.zeros((7, 3), np.int64)]
    for width in range(1, 9):
        top = (1 << (8 * width - 1)) - 1  # the largest magnitude whose zigzag fits in ``width`` bytes
        cases.append(np.array([[top, -top - 1 if width < 8 else -top], [0, -1]], dtype=np.int64))
        cases.append(rng.integers(-top // 2, top // 2, size=(50, 4), dtype=np.int64))
    for p in cases:
        rows, cols = p.shape
        packed = entropy.pack_zigzag_columns(p)
        old = entropy.unzigzag(entropy.unpack_uint64(packed, rows * cols)).reshape(cols, rows).T.copy()
        new = entropy.unpack_zigzag_columns(packed, rows, cols)
        assert new.dtype == np.int64 and new.flags.c_contiguous and np.array_equal(new, old)
        assert np.array_equal(new, p)
        assert np.array_equal(entropy.decode_int_matrix(entropy.encode_int_matrix(p, entropy.CODER_ZSTD)), p)


@pytest.mark.parametrize("rel", ["cmu/bvh/06_13.bvh", "cmu/asfamc/01_01.amc", "other/bvh/games105/idle.bvh",
                                 "other/bvh/bandai_namco/dataset-1_punch_normal_001.bvh"])
def test_positions_in_chunks_are_the_whole_clip_positions(rel: str) -> None:
    """forward_positions (a chunk of frames at a time, uneven last chunk) gives forward_kinematics' positions to
    the bit: BVH, ASF joint axes, other exporters' skeletons."""
    from mocapz.model.kinematics import forward_kinematics, forward_positions

    m = mocapz.load(data_path(rel))
    assert isinstance(m, Motion) and m.n_frames > 150
    whole = forward_kinematics(m.skeleton, m.channels)[0]
    for chunk in (37, 97, m.n_frames):
        assert np.array_equal(forward_positions(m.skeleton, m.channels, chunk), whole)
