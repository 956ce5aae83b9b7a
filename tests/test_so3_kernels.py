"""The compiled products of :func:`mocapz.codecs.pga.so3.log_between` (:mod:`mocapz.codecs.pga.so3kernels`) give
NumPy's ``mean.T @ rotation`` to the bit (signed zeros included) on a real clip's rotations, and the Karcher mean
and the tangent coordinates the PGA model is fitted with are the same numbers either way."""

from __future__ import annotations

import numpy as np
import pytest

import mocapz
from mocapz.codecs.pga import so3
from mocapz.codecs.pga.joints import inner_joints
from mocapz.model.kinematics import local_rotations
from tests.conftest import data_path

kernels = pytest.importorskip("mocapz.codecs.pga.so3kernels", exc_type=ImportError)


@pytest.fixture(scope="module")
def rotations() -> np.ndarray:
    """06_13's inner joints' local rotations ``(4906, 30, 3, 3)``: frame 0 the T-pose cgspeed adds (exact zeros
    and ones), the others a basketball player's; a strided view, as the model's callers pass them."""
    m = mocapz.load(data_path("cmu/bvh/06_13.bvh"))
    return local_rotations(m.skeleton, m.channels)[:, inner_joints(m.skeleton)]


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint64)


def test_products_equal_numpy_to_the_bit(rotations: np.ndarray) -> None:
    cols = np.array([0, 3, 7, 29, 12], dtype=np.int64)
    for mean in (rotations[0, cols], rotations[2500, cols], so3.exp(np.full((5, 3), 0.4))):
        mean = np.ascontiguousarray(mean)
        out = np.empty((len(rotations), len(cols), 3, 3))
        kernels.products_t(mean, rotations, cols, 0, len(rotations), out)
        assert np.array_equal(_bits(out), _bits(np.swapaxes(mean, -1, -2)[None] @ rotations[:, cols]))
        part = np.empty((20, len(cols), 3, 3))
        kernels.products_t(mean, rotations, cols, 100, 120, part)
        assert np.array_equal(_bits(part), _bits(out[100:120]))


def test_mean_and_tangents_the_same_with_the_kernel(rotations: np.ndarray, monkeypatch: pytest.MonkeyPatch) -> None:
    clip = rotations[:1200]
    monkeypatch.setattr(so3, "_products_kernel", lambda mean, rot: None)  # NumPy's products
    mean = so3.karcher_mean(clip)
    tangents = so3.log_between(mean, clip)
    monkeypatch.setattr(so3, "_products_kernel", lambda mean, rot: kernels)  # the kernel, compiled or not
    assert np.array_equal(_bits(so3.karcher_mean(clip)), _bits(mean))
    assert np.array_equal(_bits(so3.log_between(mean, clip)), _bits(tangents))
    some = np.array([1, 4, 5], dtype=np.int64)
    assert np.array_equal(_bits(so3.log_between(mean[some], clip, some)), _bits(tangents[:, some]))
