"""The lossless codec's numba kernels (mocapz.codecs.lossless.fast, optional: ``pip install mocapz[fast]``)
give the plain numpy path's bytes and arrays exactly: on real clips (a BVH, a C3D with gaps, an integer C3D),
and on damaged residual streams (same values, or a FormatError on both paths)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.codecs.lossless import coding, fast
from mocapz.errors import FormatError

pytest.importorskip("numba")

CLIPS = ["cmu/bvh/09_06.bvh", "cmu/bvh/02_03.bvh", "cmu/c3d/01_01.c3d",
         "other/markers/btkdata/c3d_samples/Eb015pi.c3d", "other/asfamc/amcparser/walking.amc"]


@pytest.fixture
def numpy_path() -> Iterator[None]:
    before = fast.set_enabled(False)
    yield
    fast.set_enabled(before)


def _bits(values: np.ndarray) -> np.ndarray:
    return np.nan_to_num(values, nan=0.5).view(np.int64)


def _both(fn: Callable[..., Any], *args: Any) -> tuple[Any, Any]:
    before = fast.set_enabled(False)
    try:
        slow = fn(*args)
        fast.set_enabled(True)
        assert fast.kernels(force=True) is not None
        quick = fn(*args)
    finally:
        fast.set_enabled(before)
    return slow, quick


@pytest.mark.parametrize("rel", CLIPS)
def test_numba_and_numpy_paths_are_identical(rel: str) -> None:
    motion = mocapz.load(data_path(rel))
    slow_bytes, fast_bytes = _both(mocapz.compress, motion, "lossless")
    assert slow_bytes == fast_bytes
    slow, quick = _both(mocapz.decompress, slow_bytes)
    assert np.array_equal(_bits(slow.values), _bits(quick.values))
    assert np.array_equal(_bits(quick.values), _bits(motion.values))


def test_numpy_path_works_alone(numpy_path: None) -> None:
    assert fast.kernels(force=True) is None
    motion = mocapz.load(data_path("cmu/bvh/09_06.bvh"))
    back = mocapz.decompress(mocapz.compress(motion, "lossless"))
    assert np.array_equal(_bits(back.values), _bits(motion.values))


def _outcome(data: bytes, mask: np.ndarray) -> np.ndarray | str:
    try:
        return coding.decode_residuals(data, mask)
    except FormatError:
        return "FormatError"


def test_damaged_residuals_decode_alike() -> None:
    """Random residuals with escapes, low bits and gaps; every damaged copy decodes to the same values (or
    fails) on both paths."""
    rng = np.random.default_rng(7)
    rows, cols = 300, 12
    scale = np.exp2(rng.integers(0, 14, cols))
    r = np.round(rng.laplace(0, scale, (rows, cols))).astype(np.int64)
    r[rng.random((rows, cols)) < 0.01] = 10**9
    mask = rng.random((rows, cols)) > 0.1
    r[~mask] = 0
    data = coding.encode_residuals(r, mask)
    slow, quick = _both(_outcome, data, mask)
    assert np.array_equal(slow, r) and np.array_equal(quick, r)
    for _ in range(60):
        bad = bytearray(data)
        for at in rng.integers(3, len(bad), 3):
            bad[at] ^= int(rng.integers(1, 256))
        slow, quick = _both(_outcome, bytes(bad), mask)
        assert type(slow) is type(quick)
        if isinstance(slow, np.ndarray):
            assert np.array_equal(slow, quick)


@pytest.mark.parametrize("rel", ["cmu/bvh/09_06.bvh", "other/bvh/games105/walk_and_turn_left.bvh"])
def test_batched_pursuit_matches_column_by_column(rel: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The encoder's batched predictor choice (gap-free clips) gives each column's own choice exactly, and so does
    a column's own fit (the path of clips with gaps, run here without its early stop, predict.PATIENCE)."""
    from mocapz.codecs.lossless import predict
    from mocapz.codecs.lossless.encode import column_groups, value_matrix
    from mocapz.codecs.lossless.integers import choose_form
    from mocapz.codecs.lossless.predict import choose_predictors, coding_order, shared_fit
    from mocapz.codecs.lossless.pursuit import choose_shared

    motion = mocapz.load(data_path(rel))
    values, gaps = value_matrix(motion)
    assert gaps is None
    x = choose_form(values, None if motion.decimals is None else np.broadcast_to(
        np.asarray(motion.decimals, dtype=np.int64), (values.shape[1],)), None).ints
    d2 = x[2:] - 2 * x[1:-1] + x[:-2]
    order = coding_order([[c for c in g if np.any(d2[:, c])] for g in column_groups(motion)])
    shared = shared_fit(d2, order)
    assert shared is not None
    every = np.arange(d2.shape[0])
    one_by_one = [choose_predictors(d2, c, order[:k], every, shared) for k, c in enumerate(order)]
    monkeypatch.setattr(predict, "PATIENCE", predict.MAX_PREDICTORS + 1)
    unshared = [choose_predictors(d2, c, order[:k], every) for k, c in enumerate(order)]
    batched = choose_shared(shared, order, d2.shape[0])
    for (p1, c1), (p2, c2), (p3, c3) in zip(one_by_one, batched, unshared, strict=True):
        assert p1 == p2 == p3 and np.array_equal(c1, c2) and np.array_equal(c1, c3)


def test_predictor_table_round_trip_and_damage() -> None:
    """pack_predictors -> unpack_predictors gives the table back as arrays; damaged tables give a FormatError or a
    table that still names only earlier columns of the window, never another exception."""
    from mocapz.codecs.lossless.predict import MAX_PREDICTORS, WINDOW, pack_predictors, unpack_predictors
    from mocapz.errors import FormatError

    rng = np.random.default_rng(2)
    order = [int(c) for c in rng.permutation(90)]
    table = []
    for i in range(len(order)):
        k = int(rng.integers(0, min(i, MAX_PREDICTORS) + 1))
        back = rng.choice(np.arange(1, min(i, WINDOW) + 1), size=k, replace=False) if k else np.zeros(0, int)
        table.append(([order[i - int(b)] for b in back], rng.integers(-4000, 4000, k)))
    data = pack_predictors(order, table)
    npred, pidx, pcoef = unpack_predictors(order, data)
    for i, (preds, coef) in enumerate(table):
        assert npred[i] == len(preds) and pidx[i, : len(preds)].tolist() == preds
        assert np.array_equal(pcoef[i, : len(preds)], coef) and not pidx[i, len(preds):].any()
    where = {c: i for i, c in enumerate(order)}
    for _ in range(300):
        bad = bytearray(data)
        bad[int(rng.integers(0, len(bad)))] ^= 1 << int(rng.integers(0, 8))
        try:
            npred, pidx, _ = unpack_predictors(order, bytes(bad))
        except FormatError:
            continue
        for i in range(len(order)):
            assert all(0 < i - where[int(p)] <= WINDOW for p in pidx[i, : npred[i]])
