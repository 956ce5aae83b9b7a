"""The PGA encoder's outlier frames (isolated spikes in pose space, coded apart): the detector's distances from
the trace of each joint's relative rotation give the frames the full rotation vectors (``so3.log``) give, on real
clips with spikes (cgspeed's added T-pose, 06_13's tracking spikes, an ASF/AMC clip) and without."""

from __future__ import annotations

import numpy as np
import pytest

import mocapz
from mocapz.codecs.pga import so3
from mocapz.codecs.pga.encode import prepare
from mocapz.codecs.pga.joints import inner_joints
from mocapz.codecs.pga.outliers import detect_outliers
from mocapz.model.kinematics import local_rotations
from tests.conftest import data_path


def _reference(motion: mocapz.Motion, factor: float) -> list[int]:
    """The detector's rule with every distance the norm of the joints' rotation vectors ``log(a.T @ b)``."""
    rot = local_rotations(motion.skeleton, motion.channels)[:, inner_joints(motion.skeleton)]

    def dist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.linalg.norm(so3.log(np.swapaxes(a, -1, -2) @ b).reshape(len(a), -1), axis=1)

    step, skip = dist(rot[:-1], rot[1:]), dist(rot[:-2], rot[2:])
    s = max(float(np.median(step)), 1e-9)
    out = [0] if step[0] > factor * s and step[1] < 3 * s else []
    big = step > factor * s
    out += [int(t) + 1 for t in np.flatnonzero(big[:-1] & big[1:] & (skip < factor * s))]
    if step[-1] > factor * s and step[-2] < 3 * s:
        out.append(len(rot) - 1)
    return sorted(set(out))


@pytest.mark.parametrize(("rel", "spikes"), [("cmu/bvh/06_13.bvh", 17), ("cmu/bvh/03_04.bvh", 2),
                                             ("cmu/asfamc/backflip.amc", 1), ("cmu/asfamc/01_01.amc", 0)])
def test_outliers_match_the_rotation_vector_distances(rel: str, spikes: int) -> None:
    m = mocapz.load(data_path(rel))
    found = detect_outliers(m)
    assert len(found) == spikes
    for factor in (5.0, 15.0, 30.0):
        assert detect_outliers(m, factor) == _reference(m, factor)
    local = local_rotations(m.skeleton, m.channels)
    assert detect_outliers(m, local=local) == found


def test_prepare_reuses_the_clip_rotations_to_the_bit() -> None:
    m = mocapz.load(data_path("cmu/bvh/09_12.bvh")).slice(0, 900)  # frame 0 (the T-pose) and 754 coded apart
    p = prepare(m)
    assert p.outliers == [0, 754]
    assert np.array_equal(p.clip.local_rot, local_rotations(m.skeleton, m.channels[p.kept]))
