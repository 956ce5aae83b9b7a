"""The joints the correction tightens to hold a planted foot still reach the knee, whatever the joints between,
or the hip where the knee turns about one axis."""

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


def test_a_one_axis_knee_reaches_the_hip() -> None:
    # CMU's ASF/AMC: the knee (tibia) turns about one axis, so the closed loop cannot aim it; the femur it can
    held = _held("cmu/asfamc/01_01.amc")
    assert held == {"lfemur", "ltibia", "lfoot", "ltoes", "rfemur", "rtibia", "rfoot", "rtoes"}


def test_feet_held_above_a_one_axis_knee_cost_under_three_quarters_more() -> None:
    # CMU 11_01.amc at 1 cm: the feet held 25,520 B when only the knees down were tightened (2.8 times the file
    # without them, 9,222 B), 12,982 B with the hips (1.4 times)
    m = mocapz.load(data_path("cmu/asfamc/11_01.amc"))
    free, held = (mocapz.compress(m, codec="quant", hold_feet=h) for h in (False, True))
    report = mocapz.evaluate(m, mocapz.decompress(held))
    assert report.max_err_cm <= 1.0 and report.foot_skate * m.unit_cm <= 0.5
    assert len(held) < 1.75 * len(free)
