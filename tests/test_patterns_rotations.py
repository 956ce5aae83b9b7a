"""The skeletal pattern decoder's rotations (patterns.rotvec.rotvec_euler, its kernel patterns.rotkernels) against
scipy's ``Rotation.from_rotvec(rv).as_euler(seq)``, which they stand for: the same bits for every axis sequence
(Tait-Bryan and proper Euler, intrinsic and extrinsic), for small angles (the Taylor branch), half turns and
rotations at gimbal lock (the third angle set to zero), from numba's just-in-time kernel and from the extension
compiled ahead of time; and a skeletal clip's patterns command imports no scipy module when the extension is
built (scipy.spatial cost 0.2 s of each)."""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapz import aot
from mocapz.codecs.patterns import rotvec

SEQUENCES = ["".join(p) for p in itertools.permutations("XYZ")] + ["XYX", "XZX", "YXY", "YZY", "ZXZ", "ZYZ"]


def _scipy(rv: np.ndarray, seq: str) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Rotation.from_rotvec(rv).as_euler(seq)


def _vectors(seq: str) -> np.ndarray:
    """Rotation vectors of every kind: ordinary, tiny (under and at 1e-3 rad), zero, half turns, long (several
    turns) and at gimbal lock for ``seq`` (middle angle 0, +-pi/2 or pi)."""
    rng = np.random.default_rng(7)
    axes = np.eye(3)
    gimbal = rng.uniform(-3.0, 3.0, (400, 3))
    middle = (0.0, np.pi) if seq[0].upper() == seq[2].upper() else (np.pi / 2, -np.pi / 2)
    gimbal[:, 1] = rng.choice(middle, 400)
    return np.concatenate([rng.normal(size=(4000, 3)), rng.normal(size=(1000, 3)) * 3e-4,
                           rng.uniform(-9.0, 9.0, (1000, 3)), np.zeros((1, 3)), np.pi * axes, -np.pi * axes,
                           1e-3 * axes, np.nextafter(1e-3, 1.0) * axes,
                           _scipy_rotvec(seq, gimbal)])


def _scipy_rotvec(seq: str, angles: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Rotation.from_euler(seq, angles).as_rotvec()


def _kernel_angles(fn, rv: np.ndarray, seq: str) -> tuple[np.ndarray, int]:  # noqa: ANN001 (a kernel)
    extrinsic = seq.islower()
    axes = rotvec.scipy_axes(seq.upper()[::-1] if extrinsic else seq)
    out = np.empty_like(rv)
    return out, fn(np.ascontiguousarray(rv), axes, extrinsic, out)


@pytest.mark.parametrize("seq", SEQUENCES + [s.lower() for s in SEQUENCES[:6]])
def test_the_kernel_gives_scipys_bits(seq: str) -> None:
    rotkernels = pytest.importorskip("mocapz.codecs.patterns.rotkernels")
    rv = _vectors(seq)
    out, singular = _kernel_angles(rotkernels.rotvec_euler, rv, seq)
    ref = _scipy(rv, seq)
    np.testing.assert_array_equal(out, ref)
    assert singular >= 400  # the gimbal-lock rows took scipy's singular branch (and agree)


def test_the_extension_and_the_fallback_give_scipys_bits(monkeypatch: pytest.MonkeyPatch) -> None:
    rv = _vectors("ZXY")
    ref = _scipy(rv, "ZXY")
    if aot.extension() is not None:
        assert aot.kernels("rot") is not None
        np.testing.assert_array_equal(rotvec.rotvec_euler("zxy", rv), ref)
    monkeypatch.setattr(aot, "kernels", lambda alias: None)  # no extension: scipy itself
    np.testing.assert_array_equal(rotvec.rotvec_euler("ZXY", rv), ref)
    assert rotvec.rotvec_euler("ZXY", rv[:0]).shape == (0, 3)
