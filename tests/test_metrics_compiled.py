"""The compiled point errors (mocapz.metrics.errkernels) give NumPy's ``np.linalg.norm(a - b, axis=-1)`` to the bit:
on a C3D file's markers with gaps (NaN where NumPy gives NaN), on strided views, through ``figures.point_errors``
where the extension is built."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz import _jit, aot
from mocapz.metrics import figures

pytest.importorskip("numba")
from mocapz.metrics import errkernels  # noqa: E402  (numba's)


def _same(got: np.ndarray, want: np.ndarray) -> bool:
    gap = np.isnan(want)
    return bool(np.array_equal(np.isnan(got), gap)
                and np.array_equal(np.where(gap, 0.0, got).view(np.uint64), np.where(gap, 0.0, want).view(np.uint64)))


def test_point_errors_kernel_gives_numpys_bits_on_markers_with_gaps() -> None:
    m = mocapz.load(data_path("other/markers/btkdata/Gait.trc"))
    a = np.asarray(m.positions, dtype=np.float64)
    assert np.isnan(a).any()  # the file's gaps
    b = a + np.random.default_rng(5).normal(size=a.shape) * 0.7
    for x, y in ((a, b), (a[:, ::3], b[:, ::3]), (a[1:], b[:-1])):
        want = np.linalg.norm(x - y, axis=-1)
        got = np.empty(want.shape)
        errkernels.point_errors(x, y, got)
        assert _same(got, want)


def test_figures_take_the_extension_with_the_same_numbers() -> None:
    if aot.extension() is None:
        pytest.skip("the kernels are not built ahead of time here (`make kernels`): NumPy's path is taken")
    m = mocapz.load(data_path("cmu/bvh/06_13.bvh"))
    a = m.positions()
    b = a + np.random.default_rng(6).normal(size=a.shape)
    assert figures._err_kernel(a, b) is not None
    got = figures.point_errors(a, b)
    before = _jit.set_enabled(False)
    try:
        assert figures._err_kernel(a, b) is None
        want = figures.point_errors(a, b)
    finally:
        _jit.set_enabled(before)
    assert _same(got, want)
    assert figures._err_kernel(a.astype(np.float32), b) is None  # another dtype: NumPy's path


@pytest.mark.parametrize("rel", ["cmu/bvh/06_13.bvh", "cmu/asfamc/01_01.amc",
                                 "other/bvh/bandai_namco/dataset-1_dance-short_normal_001.bvh"])
def test_the_corrections_levers_are_numpys(rel: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The correction's levers (the longest distance from a joint to a point below it, :func:`bounds._levers`) from
    the compiled ``farthest`` (just in time here, and through the extension where built) are NumPy's norms' maxima
    to the bit, on real skeletons, with a NaN frame (NaN where NumPy's max gives NaN)."""
    from mocapz.codecs.correction import bounds
    from mocapz.model.kinematics import forward_positions

    m = mocapz.load(data_path(rel)).slice(0, 900)
    pos = forward_positions(m.skeleton, m.channels)
    below = m.skeleton.below()
    hurt = pos.copy()
    hurt[400, 5, 1] = np.nan
    for p in (pos, hurt):
        with monkeypatch.context() as mp:
            mp.setattr(_jit, "_ENABLED", False)
            want = bounds._levers(p, below)
        joints, points = np.nonzero(below)
        far = np.empty(joints.size)
        errkernels.farthest(p, joints.astype(np.int64), points.astype(np.int64), far)
        assert _same(np.maximum.reduceat(far, np.flatnonzero(np.diff(joints, prepend=-1))), want[below.any(axis=1)])
        assert _same(bounds._levers(p, below), want)
    assert np.isnan(bounds._levers(hurt, below)).any() and not np.isnan(bounds._levers(pos, below)).any()
