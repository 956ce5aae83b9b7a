"""The decoder's compiled kernels (:func:`mocapz.codecs.correction.lifting.decode_table`,
:func:`mocapz.codecs.pga.lifting.decode_rn`) give the NumPy path's values to the bit, and the in-place /
chunked NumPy helpers of the decoders (unwrap, unzigzag, so3.hat) the values of the formulas they replace."""

from __future__ import annotations

import numpy as np
import pytest

from mocapz.codecs.correction import compiled
from mocapz.codecs.correction import lifting as clift
from mocapz.codecs.pga import ikjit, so3
from mocapz.codecs.pga import lifting as plift
from mocapz.codecs.pga.channels import unwrap_columns
from mocapz.format.entropy import unzigzag, zigzag


def _both(fn: object, *args: object) -> tuple[np.ndarray, np.ndarray]:
    """``fn(*args)`` with the compiled kernels, then without."""
    old = ikjit.set_enabled(True)
    try:
        a = fn(*args)  # type: ignore[operator]
        ikjit.set_enabled(False)
        b = fn(*args)  # type: ignore[operator]
    finally:
        ikjit.set_enabled(old)
    return a, b


def test_correction_decode_table_equal(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("numba")
    monkeypatch.setattr(compiled, "LAZY_FRAMES", 0)
    monkeypatch.setattr(compiled, "LAZY_DECODE_FRAMES", 0)
    rng = np.random.default_rng(5)
    for _ in range(40):
        frames, groups, depth = int(rng.integers(1, 700)), int(rng.integers(1, 5)), int(rng.integers(0, 7))
        cols = np.sort(rng.integers(0, groups, size=int(rng.integers(1, 9))))
        lev = rng.integers(0, 12, size=(frames, groups))
        halves = 2.0 ** (-np.arange(12, dtype=np.float64) / 2.0)
        tol_col = rng.uniform(0.01, 2.0, size=cols.size)
        tol_col[0] = 1e40 if rng.random() < 0.3 else tol_col[0]
        tol = tol_col[None, :] * halves[lev][:, cols]
        shrink = float(rng.choice([1.0, 0.85, 0.7]))
        x = np.cumsum(rng.normal(size=(frames, cols.size)), axis=0)
        q, y = clift.quantise(x, tol, depth, shrink, compiled=False)
        a, b = _both(clift.decode_table, q, tol_col, halves, lev, cols, depth, shrink)
        assert np.array_equal(a, b)
        assert np.array_equal(a, clift.decode(q, tol, depth, shrink))
        assert np.array_equal(a, y)


def test_pga_decode_rn_equal() -> None:
    pytest.importorskip("numba")
    rng = np.random.default_rng(6)
    ikjit.kernels()  # numba loaded: the kernel whatever the length
    for n in (1, 2, 3, 5, 8, 9, 17, 100, 513, 1000):
        for lod in (0, 1, 3):
            x = np.cumsum(rng.normal(size=(n, 4)), axis=0)
            q, recon = plift.encode_rn(x, 0.01, lod)
            a, b = _both(plift.decode_rn, q, n, 0.01, lod)
            assert np.array_equal(a, b)
            assert np.array_equal(a, recon)


def test_unwrap_columns_matches_np_unwrap() -> None:
    rng = np.random.default_rng(7)
    for frames in (0, 1, 2, 700, 1500):
        v = rng.uniform(-180, 180, size=(frames, 6))
        v[:, :3] = np.cumsum(rng.normal(size=(frames, 3)), axis=0)  # smooth columns: no jumps
        v[: min(frames, 3), 1] = -0.0
        cols = np.array([True, True, False, True, True, True])
        out = v.copy()
        unwrap_columns(out, cols, 360.0)
        ref = v.copy()
        ref[:, cols] = np.unwrap(v[:, cols], period=360.0, axis=0) if frames else v[:, cols]
        ref[:, :2] = v[:, :2] + 0.0
        assert np.array_equal(out, ref)
        assert np.array_equal(np.signbit(out), np.signbit(ref))


def test_unzigzag_and_hat() -> None:
    rng = np.random.default_rng(8)
    v = np.concatenate([rng.integers(-2**62, 2**62, 1000), [0, -1, 1, 2**63 - 1, -2**63]])
    assert np.array_equal(unzigzag(zigzag(v)), v)
    assert int(unzigzag(np.uint64(3))) == -2
    w = rng.normal(size=(50, 2, 3))
    z = np.zeros(w.shape[:-1])
    x, y, t = w[..., 0], w[..., 1], w[..., 2]
    ref = np.stack([np.stack([z, -t, y], -1), np.stack([t, z, -x], -1), np.stack([-y, x, z], -1)], -2)
    assert np.array_equal(so3.hat(w), ref)
