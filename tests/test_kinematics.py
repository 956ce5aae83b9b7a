"""Forward kinematics: the vectorised Euler rotations equal scipy's, on every rotation order and on real
skeletons (BVH, ASF joint axes, partial rotation channels)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path
from scipy.spatial.transform import Rotation

import mocapz
from mocapz.model.kinematics import POSITION_CHUNK, euler_rotations, local_rotations


@pytest.mark.parametrize("order", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX", "ZX", "YZ", "X", "XYX"])
def test_euler_rotations_equal_scipy(order: str) -> None:
    a = np.random.default_rng(len(order)).uniform(-7, 7, size=(500, len(order)))
    want = Rotation.from_euler(order, a).as_matrix()
    assert np.abs(euler_rotations(a, order) - want).max() < 1e-14


@pytest.mark.parametrize("rel", ["cmu/bvh/09_06.bvh", "cmu/asfamc/01_01.amc", "other/bvh/games105/idle.bvh",
                                 "other/bvh/bandai_namco/dataset-1_punch_normal_001.bvh"])
def test_local_rotations_equal_scipy_on_real_skeletons(rel: str) -> None:
    m = mocapz.load(data_path(rel))
    sk, ch = m.skeleton, m.channels[:200]
    scale = np.pi / 180.0 if sk.angle_unit == "deg" else 1.0
    got = local_rotations(sk, ch)
    for j, (sl, chs, order) in enumerate(zip(sk.channel_slices(), sk.channels, sk.rotation_order, strict=True)):
        if not order:
            assert np.array_equal(got[:, j], np.broadcast_to(np.eye(3), got[:, j].shape))
            continue
        r = Rotation.from_euler(order, ch[:, [sl.start + chs.index(f"{a}rotation") for a in order]] * scale)
        want = sk.axis[j] @ r.as_matrix() @ sk.axis[j].T
        assert np.abs(got[:, j] - want).max() < 1e-14, (rel, j)


@pytest.mark.parametrize("order", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])
def test_euler_angles_invert_euler_rotations(order: str) -> None:
    """Angles back from the rotations (the middle one in [-90, 90] degrees), gimbal lock included."""
    from mocapz.model.kinematics import euler_angles

    rng = np.random.default_rng(1)
    a = rng.uniform(-np.pi, np.pi, (500, 3))
    a[:, 1] = rng.uniform(-1.5, 1.5, 500)
    a[:5, 1], a[5:10, 1] = np.pi / 2, -np.pi / 2
    r = euler_rotations(a, order)
    b = euler_angles(r, order)
    assert np.abs(euler_rotations(b, order) - r).max() < 1e-12
    assert np.abs(b[10:] - a[10:]).max() < 1e-12


def test_local_rotations_in_chunks_are_the_whole_clips() -> None:
    """Frames a chunk at a time (small temporaries) give the bits of every frame at once."""
    m = mocapz.load(data_path("cmu/bvh/06_13.bvh"))
    sk = m.skeleton
    chunked = local_rotations(sk, m.channels)
    assert m.n_frames > 2 * POSITION_CHUNK
    whole = np.broadcast_to(np.eye(3), chunked.shape).copy()
    scale = np.pi / 180.0
    for j, (sl, chs, order) in enumerate(zip(sk.channel_slices(), sk.channels, sk.rotation_order, strict=True)):
        if order:
            cols = [sl.start + chs.index(f"{a}rotation") for a in order]
            whole[:, j] = euler_rotations(m.channels[:, cols] * scale, order)
    assert np.array_equal(chunked, whole)
