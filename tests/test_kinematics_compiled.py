"""The compiled forward kinematics (mocapz.model.fkkernels) gives NumPy's positions and global rotations to the bit:
on real skeletons of every kind the shared files hold (CMU BVH and ASF/AMC with joint axes and one- or two-axis
joints, Bandai's position channels on every joint, an iClone rig, end sites everywhere), on angles of several
turns, on gaps; and ``mocapz.model.kinematics`` takes it (the extension built ahead of time) without another
number."""

from __future__ import annotations

import copy
from collections.abc import Iterator

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz import _jit, aot
from mocapz.model import kinematics

pytest.importorskip("numba")
from mocapz.model import fkkernels  # noqa: E402  (numba's)

FILES = ["cmu/bvh/06_13.bvh", "cmu/asfamc/01_01.amc", "other/bvh/bandai_namco/dataset-1_punch_normal_001.bvh",
         "cmu/bvh_iclone_ccrig/002_03.bvh", "other/bvh/bvh-python/test_mocapbank.bvh", "other/bvh/games105/idle.bvh"]


@pytest.fixture
def numpy_path() -> Iterator[None]:
    """kinematics' NumPy path (numba turned off, as without it)."""
    before = _jit.set_enabled(False)
    try:
        yield
    finally:
        _jit.set_enabled(before)


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint64)


def _kernel(sk: mocapz.Skeleton, ch: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The just-in-time kernel's positions and rotations, and its positions alone (``keep`` False)."""
    ch = np.ascontiguousarray(ch, dtype=np.float64)
    pos, rot = np.empty((ch.shape[0], sk.n_points, 3)), np.empty((ch.shape[0], sk.n_joints, 3, 3))
    fkkernels.forward(ch, *kinematics._tables(sk), pos, rot, True)
    alone = np.empty_like(pos)
    fkkernels.forward(ch, *kinematics._tables(sk), alone, np.empty((1, sk.n_joints, 3, 3)), False)
    return pos, rot, alone


def _local(sk: mocapz.Skeleton, ch: np.ndarray) -> np.ndarray:
    """The just-in-time kernel's local rotations (:func:`kinematics.local_rotations`)."""
    out = np.empty((ch.shape[0], sk.n_joints, 3, 3))
    scale, _, rot_cols, rot_axes, n_rot, turned, axis = kinematics._tables(sk)[:7]
    fkkernels.local(np.ascontiguousarray(ch, dtype=np.float64), scale, rot_cols, rot_axes, n_rot, turned, axis, out)
    return out


@pytest.mark.parametrize("rel", FILES)
def test_the_kernel_gives_numpys_bits_on_real_skeletons(rel: str, numpy_path: None) -> None:  # noqa: ARG001
    m = mocapz.load(data_path(rel))
    want_pos, want_rot = kinematics.forward_kinematics(m.skeleton, m.channels)
    pos, rot, alone = _kernel(m.skeleton, m.channels)
    assert np.array_equal(_bits(pos), _bits(want_pos)) and np.array_equal(_bits(rot), _bits(want_rot))
    assert np.array_equal(_bits(alone), _bits(want_pos))
    assert np.array_equal(_bits(kinematics.forward_positions(m.skeleton, m.channels)), _bits(want_pos))
    assert np.array_equal(_bits(_local(m.skeleton, m.channels)), _bits(kinematics.local_rotations(m.skeleton,
                                                                                                   m.channels)))


def test_the_kernel_gives_numpys_bits_on_wide_angles_and_gaps(numpy_path: None) -> None:  # noqa: ARG001
    """ASF 01_01's skeleton (joint axes, partial rotation channels) on angles up to four turns either way and
    translations of a few metres; a gap (NaN) in a channel makes NaN where NumPy does, nowhere else."""
    m = mocapz.load(data_path("cmu/asfamc/01_01.amc"))
    rng = np.random.default_rng(7)
    ch = rng.uniform(-1440.0, 1440.0, size=(300, m.channels.shape[1]))
    ch[rng.random(ch.shape) < 0.002] = np.nan
    want_pos, want_rot = kinematics.forward_kinematics(m.skeleton, ch)
    pos, rot, alone = _kernel(m.skeleton, ch)
    for got, want in ((pos, want_pos), (rot, want_rot), (alone, want_pos)):
        gap = np.isnan(want)
        assert np.array_equal(np.isnan(got), gap)
        assert np.array_equal(_bits(np.where(gap, 0.0, got)), _bits(np.where(gap, 0.0, want)))


def test_kinematics_takes_the_extension_with_the_same_numbers() -> None:
    """Where the kernels are built ahead of time, forward_kinematics and forward_positions call them (numba not
    imported for it) and give the NumPy path's bits."""
    if aot.extension() is None:
        pytest.skip("the kernels are not built ahead of time here (`make kernels`): NumPy's path is taken")
    m = mocapz.load(data_path("cmu/bvh/06_13.bvh"))
    assert kinematics._kernel() is not None
    got = kinematics.forward_kinematics(m.skeleton, m.channels), kinematics.forward_positions(m.skeleton, m.channels)
    before = _jit.set_enabled(False)
    try:
        assert kinematics._kernel() is None
        want = kinematics.forward_kinematics(m.skeleton, m.channels)
    finally:
        _jit.set_enabled(before)
    assert np.array_equal(_bits(got[0][0]), _bits(want[0])) and np.array_equal(_bits(got[0][1]), _bits(want[1]))
    assert np.array_equal(_bits(got[1]), _bits(want[0]))


def test_the_kernel_gives_numpys_bits_on_an_odd_skeleton(numpy_path: None) -> None:  # noqa: ARG001
    """Channels in any order with positions on a non-root joint, a repeated axis (ZXZ), one-axis and two-axis
    joints, a joint without channels, an end site on the root, radians."""
    from mocapz.model.skeleton import Skeleton

    rng = np.random.default_rng(3)
    sk = Skeleton(names=["root", "a", "b", "c", "d"], parents=np.array([-1, 0, 1, 1, 3]),
                  offsets=rng.normal(size=(5, 3)) * 10,
                  channels=[("Yposition", "Xrotation", "Xposition", "Zrotation", "Zposition", "Yrotation"),
                            ("Zrotation", "Xrotation", "Zrotation"), ("Yrotation",), (),
                            ("Xposition", "Yrotation", "Xrotation")],
                  rotation_order=["XZY", "ZXZ", "Y", "", "YX"],
                  end_sites=[(2, rng.normal(size=3), "e1"), (4, rng.normal(size=3), "e2"),
                             (0, rng.normal(size=3), "e3")], angle_unit="rad")
    ch = rng.uniform(-9.0, 9.0, size=(500, sk.n_channels))
    want_pos, want_rot = kinematics.forward_kinematics(sk, ch)
    pos, rot, alone = _kernel(sk, ch)
    assert np.array_equal(_bits(pos), _bits(want_pos)) and np.array_equal(_bits(rot), _bits(want_rot))
    assert np.array_equal(_bits(alone), _bits(want_pos))
    assert np.array_equal(_bits(_local(sk, ch)), _bits(kinematics.local_rotations(sk, ch)))


def test_a_skeleton_changed_in_place_is_not_given_its_old_tables() -> None:
    """The kernels' tables are made once per skeleton and kept by what they are made of: the same object asked
    again gets the kept ones; its offsets, channels or end sites changed in place, new ones, and the compiled
    positions follow the NumPy path's."""
    m = mocapz.load(data_path("cmu/bvh/09_06.bvh")).slice(0, 40)
    sk = copy.deepcopy(m.skeleton)  # changed below: not the loaded clip's (a cache may share it)
    first = kinematics._tables(sk)
    assert kinematics._tables(sk) is first
    sk.offsets[3] *= 2.0  # a longer bone
    sk.end_sites[0] = (sk.end_sites[0][0], np.asarray(sk.end_sites[0][1]) + 1.0, sk.end_sites[0][2])
    second = kinematics._tables(sk)
    assert second is not first
    got = kinematics.forward_positions(sk, m.channels)
    before = _jit.set_enabled(False)
    try:
        want = kinematics.forward_positions(sk, m.channels)
    finally:
        _jit.set_enabled(before)
    assert np.array_equal(_bits(got), _bits(want))
    sk.channels[0] = tuple(reversed(sk.channels[0]))  # the root's channels in another order
    assert kinematics._tables(sk) is not second
