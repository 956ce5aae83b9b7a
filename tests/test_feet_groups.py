"""The joints the correction tightens to hold a planted foot still reach the knee, whatever the joints between."""

from __future__ import annotations

from conftest import data_path

import mocapz
from mocapz.codecs.correction.fit import Clip


def _held(rel: str) -> set[str]:
    m = mocapz.load(data_path(rel))
    clip = Clip(m, hold_feet=True)
    return {m.skeleton.names[j] for j in clip.foot_groups().nonzero()[0]}


def test_cmu_feet_up_to_the_knees() -> None:
    assert _held("cmu/bvh/02_01.bvh") == {"LeftToeBase", "LeftFoot", "LeftLeg", "RightToeBase", "RightFoot", "RightLeg"}


def test_asf_with_a_mid_foot_joint_up_to_the_knees() -> None:
    held = _held("other/asfamc/amcparser/walking.amc")
    assert {"LeftKneeJoint", "RightKneeJoint", "LeftMidFootJoint", "LeftAnkleJoint"} <= held
    assert not held & {"LeftHipJoint", "RightHipJoint", "root"}
