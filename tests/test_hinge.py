"""The closed loop aims the joints that turn about one or two axes (CMU's ASF/AMC knees, elbows, feet, hands,
clavicles) at the original point below them: the original angles under the original parent, the child nearer
than the original angles put it under a decoded (perturbed) parent, the ASF/AMC codes about as small as the
BVH of the same motion, and a BVH rewritten with one-axis knees and elbows (as some exporters write them) codes
smaller with them aimed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import data_path
from scipy.spatial.transform import Rotation

import mocapz
from mocapz.codecs.correction import hinge
from mocapz.codecs.correction.chain import Chain
from mocapz.model.kinematics import forward_kinematics

LONG = {"tibia", "foot", "clavicle", "radius"}  # the hinges with bones of 10 cm and more (toes, hands, thumbs: shorter)


@pytest.fixture(scope="module")
def amc() -> tuple[mocapz.Motion, np.ndarray, np.ndarray, Chain]:
    m = mocapz.load(data_path("cmu/asfamc/01_01.amc")).slice(0, 400)
    pos, g = forward_kinematics(m.skeleton, m.channels)
    return m, pos, g, Chain(m, pos, g)


def _child_after(m: mocapz.Motion, chain: Chain, j: int, gp: np.ndarray, p_dec: np.ndarray,
                 values: np.ndarray) -> np.ndarray:
    """``(frames, 3)`` where joint ``j``'s child lands with channel ``values`` under parent rotations ``gp``."""
    from mocapz.codecs.correction.hinge import child_offset  # noqa: PLC0415

    local = chain._local(j, values)
    return p_dec[:, j] + np.einsum("fab,fb->fa", gp @ local, np.broadcast_to(
        child_offset(m.skeleton, int(chain.aim[j])), (len(gp), 3)))


def test_the_hinges_of_an_asf_skeleton(amc: tuple) -> None:
    m, _, _, chain = amc
    names = {m.skeleton.names[j] for j, h in enumerate(chain.hinge) if h is not None}
    assert {"ltibia", "rtibia", "lradius", "rradius", "lfoot", "rfoot", "lclavicle", "rclavicle"} <= names
    assert not names & {"root", "lfemur", "rfemur", "lhumerus", "rhumerus"}  # three axes: the loop's own aim


def test_the_original_parent_gives_back_the_original_angles(amc: tuple) -> None:
    m, pos, g, chain = amc
    for j, cols in enumerate(chain.hinge):
        if cols is None:
            continue
        residual = np.zeros_like(m.channels)
        chain._hinge_residual(j, g[:, m.skeleton.parents[j]], pos, m.channels, residual)
        assert np.abs(residual[:, cols]).max() < 1e-9, m.skeleton.names[j]


def test_a_decoded_parent_aims_the_child_nearer(amc: tuple) -> None:
    m, pos, g, chain = amc
    rng = np.random.default_rng(7)
    sk = m.skeleton
    for j, cols in enumerate(chain.hinge):
        if cols is None:
            continue
        turn = Rotation.from_rotvec(rng.normal(scale=0.03, size=(m.n_frames, 3))).as_matrix()
        gp = turn @ g[:, sk.parents[j]]  # the parent decoded a few degrees off
        p_dec = pos.copy()
        p_dec[:, j] += rng.normal(scale=0.3, size=(m.n_frames, 3))  # and the joint 0.3 units off (1.7 cm)
        residual = np.zeros_like(m.channels)
        chain._hinge_residual(j, gp, p_dec, m.channels, residual)
        sl = chain.slices[j]
        aimed = m.channels[:, sl] + residual[:, sl]
        goal = pos[:, int(chain.aim[j])]
        near = np.linalg.norm(_child_after(m, chain, j, gp, p_dec, aimed) - goal, axis=1)
        plain = np.linalg.norm(_child_after(m, chain, j, gp, p_dec, m.channels[:, sl]) - goal, axis=1)
        assert np.all(near <= plain + 1e-9), sk.names[j]
        assert near.mean() < plain.mean(), sk.names[j]
        if sk.names[j][1:] in LONG:  # a short bone's aim turns more than the loop allows on many frames
            assert near.mean() < 0.8 * plain.mean(), sk.names[j]


def test_an_asf_amc_codes_near_the_bvh_of_the_same_motion() -> None:
    # CMU 01_01 at 1 cm, feet held, first 1,200 frames: the BVH 8,237 B; the ASF/AMC 49,038 B with only the knees
    # down holding its feet and no hinge aimed, 27,870 B with the hips holding them, 11,581 B with the hinges aimed
    amc = mocapz.load(data_path("cmu/asfamc/01_01.amc")).slice(0, 1200)
    bvh = mocapz.load(data_path("cmu/bvh/01_01.bvh")).slice(0, 1200)
    coded = {k: mocapz.compress(m, codec="quant") for k, m in (("amc", amc), ("bvh", bvh))}
    report = mocapz.evaluate(amc, mocapz.decompress(coded["amc"]))
    assert report.max_err_cm <= 1.0 and report.foot_skate * amc.unit_cm <= 0.5 and report.jitter_pct <= 4.5
    assert len(coded["amc"]) < 1.6 * len(coded["bvh"])


def _one_axis_knees_and_elbows(src: str, dst: Path) -> None:
    """Rewrite a BVH as some exporters write hinges: knees and elbows keep their X rotation channel only (the
    other two dropped from the hierarchy and from every frame)."""
    hinges = {"LeftLeg", "RightLeg", "LeftForeArm", "RightForeArm"}
    out, drop, col, joint, motion = [], set(), 0, "", False
    for line in Path(src).read_text().splitlines():
        words = line.split()
        if motion and words and not line.startswith("Frame"):
            line = " ".join(w for i, w in enumerate(words) if i not in drop)
        elif words[:1] in (["ROOT"], ["JOINT"]):
            joint = words[1]
        elif words[:1] == ["CHANNELS"]:
            if joint in hinges:
                drop |= {col + i for i, c in enumerate(words[2:]) if c != "Xrotation"}
                line = line[:line.index("CHANNELS")] + "CHANNELS 1 Xrotation"
            col += int(words[1])
        motion = motion or words == ["MOTION"]
        out.append(line)
    dst.write_text("\n".join(out) + "\n")


def test_a_bvh_with_one_axis_knees_and_elbows_aims_them(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # CMU 02_05 rewritten with X-only knees and elbows, first 900 frames at 1 cm: 5,507 B with the hinges aimed,
    # 6,776 B without (the knees, elbows and their children then coded against their own original angles)
    path = tmp_path / "hinged.bvh"
    _one_axis_knees_and_elbows(data_path("cmu/bvh/02_05.bvh"), path)
    m = mocapz.load(path).slice(0, 900)
    assert [m.skeleton.rotation_order[m.skeleton.names.index(n)] for n in ("LeftLeg", "RightForeArm")] == ["X", "X"]
    aimed = mocapz.compress(m, codec="quant")
    report = mocapz.evaluate(m, mocapz.decompress(aimed))
    assert report.max_err_cm <= 1.0 and report.foot_skate * m.unit_cm <= 0.5 and report.jitter_pct <= 4.5
    monkeypatch.setattr(hinge, "columns", lambda *args: None)
    assert len(aimed) < 0.9 * len(mocapz.compress(m, codec="quant"))


@pytest.mark.parametrize("wobble", [0.03, 0.6])
def test_the_compiled_hinge_aim_is_numpys(amc: tuple, wobble: float) -> None:
    """:func:`.chainkernels.hinge_residual` gives :meth:`Chain._hinge_residual`'s NumPy residuals to float rounding,
    on every hinge (one axis and two) under parents decoded a little or far off (``wobble`` radians: far enough
    that many frames keep their original angles)."""
    from mocapz.codecs.correction.compiled import kernels  # noqa: PLC0415

    kern = kernels(1 << 30)  # whatever the clip's length (numba loaded where not compiled ahead of time)
    if kern is None:
        pytest.skip("no compiled kernels")
    m, pos, g, chain = amc
    rng = np.random.default_rng(11)
    sk = m.skeleton
    seen = set()
    for j, cols in enumerate(chain.hinge):
        if cols is None:
            continue
        seen.add(len(cols))
        gp = np.ascontiguousarray(Rotation.from_rotvec(rng.normal(scale=wobble, size=(m.n_frames, 3))).as_matrix()
                                  @ g[:, sk.parents[j]])
        p_dec = pos + rng.normal(scale=0.3, size=pos.shape)
        plain, fast = np.zeros_like(m.channels), np.zeros_like(m.channels)
        chain._hinge_residual(j, gp, p_dec, m.channels, plain)
        chain._hinge_residual(j, gp, p_dec, m.channels, fast, kern)
        assert np.abs(fast - plain).max() <= 1e-9, sk.names[j]
    assert seen == {1, 2}
