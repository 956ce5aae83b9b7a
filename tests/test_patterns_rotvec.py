"""The pattern codec's rotation vectors, all frames at once: scipy's numbers, and the loop's continuity."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path
from scipy.spatial.transform import Rotation

import mocapz
from mocapz.codecs.patterns.rotvec import continuous_rotvec, euler_rotvec


def _loop(rv: np.ndarray) -> np.ndarray:
    """The frame-by-frame rule: each frame's vector, or its other form, whichever is nearer the one before."""
    out = rv.copy()
    if not (np.linalg.norm(rv, axis=1) > 2.0).any():
        return out
    for t in range(1, len(out)):
        n = np.linalg.norm(out[t])
        if n > 1e-9:
            alt = out[t] * (1.0 - 2.0 * np.pi / n)
            if np.linalg.norm(alt - out[t - 1]) < np.linalg.norm(out[t] - out[t - 1]):
                out[t] = alt
    return out


@pytest.mark.parametrize("order", ["ZYX", "XYZ", "zxy", "YZX", "XZY", "YXZ", "ZXZ", "yzy"])
def test_euler_rotvec_is_scipys(order: str) -> None:
    rng = np.random.default_rng(3)
    angles = rng.uniform(-4.0, 4.0, (5000, 3))
    angles[:20] = 0.0
    angles[20:40] = rng.uniform(-1e-4, 1e-4, (20, 3))  # the small-angle series
    ours = euler_rotvec(order, angles)
    theirs = Rotation.from_euler(order.upper(), angles).as_rotvec()
    assert np.abs(ours - theirs).max() < 1e-14


def test_continuous_rotvec_is_the_loop_on_random_turns() -> None:
    rng = np.random.default_rng(4)
    for _ in range(100):
        n = int(rng.integers(2, 300))
        rv = Rotation.from_rotvec(np.cumsum(rng.normal(0.0, 0.4, (n, 3)), axis=0)).as_rotvec()
        rv[rng.integers(0, n, 2)] = 0.0  # frames with no direction to unroll along
        expected = _loop(rv)
        got = continuous_rotvec(rv)
        assert np.array_equal(got, expected)
        # each frame's form is the nearer of the two to the frame before as made continuous
        norms = np.linalg.norm(got, axis=1)
        other = got - 2.0 * np.pi * got / np.where(norms > 0, norms, 1.0)[:, None]
        step, other_step = (np.linalg.norm(v[1:] - got[:-1], axis=1) for v in (got, other))
        assert (step <= other_step + 1e-9)[norms[1:] > 1e-9].all()


def test_continuous_rotvec_is_the_loop_on_shared_clips() -> None:
    checked = 0
    for rel in ("cmu/bvh/06_13.bvh", "other/bvh/bandai_namco/dataset-1_dance-short_normal_001.bvh"):
        m = mocapz.load(data_path(rel))
        sk, start = m.skeleton, 0
        for j in range(sk.n_joints):
            rot = [start + k for k, c in enumerate(sk.channels[j]) if c.endswith("rotation")]
            start += len(sk.channels[j])
            if len(rot) != 3:
                continue
            rv = euler_rotvec(sk.rotation_order[j], np.deg2rad(m.channels[:, rot]))
            assert np.array_equal(continuous_rotvec(rv), _loop(rv))
            checked += 1
    assert checked >= 40  # every joint with three rotation channels
