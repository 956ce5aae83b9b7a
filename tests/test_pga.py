"""PGA codec: the paper's steps on synthetic and real data, rate control, editing, bad parameters."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.codecs.pga import lifting, so3
from mocapz.codecs.pga.effectors import find_effectors
from mocapz.codecs.pga.encode import encode_prepared, prepare
from mocapz.codecs.pga.ik import IKProblem, solve
from mocapz.codecs.pga.joints import inner_joints
from mocapz.codecs.pga.model import fit_pga
from mocapz.codecs.pga.params import PGASettings
from mocapz.edit import edit, effector_trajectories
from mocapz.errors import OptionError, TargetError
from mocapz.model.kinematics import forward_kinematics, local_rotations, local_translations
from mocapz.model.skeleton import Skeleton


@pytest.fixture(scope="module")
def run_clip() -> mocapz.Motion:
    return mocapz.load(data_path("cmu/bvh/09_06.bvh"))


def test_exp_log_round_trip() -> None:
    rng = np.random.default_rng(0)
    w = rng.normal(size=(500, 3))
    w *= (rng.uniform(0, np.pi - 1e-3, 500) / np.linalg.norm(w, axis=1))[:, None]
    assert np.allclose(so3.log(so3.exp(w)), w, atol=1e-9)
    r = so3.exp(w)
    assert np.allclose(r @ np.swapaxes(r, -1, -2), np.eye(3), atol=1e-12)


def test_karcher_mean_and_pga_recover_known_model() -> None:
    rng = np.random.default_rng(1)
    n_joints = 4
    mu = so3.exp(rng.normal(size=(n_joints, 3)))
    v, _ = np.linalg.qr(rng.normal(size=(3 * n_joints, 2)))
    t = np.linspace(-1.0, 1.0, 41)
    # samples along each direction separately: uncorrelated coordinates, symmetric about zero, so the
    # intrinsic mean is exactly mu and the principal directions are exactly v (variances 0.25 : 0.01)
    coef = np.concatenate([np.stack([0.5 * t, 0 * t], 1), np.stack([0 * t, 0.1 * t], 1)])
    poses = mu[None] @ so3.exp((coef @ v.T).reshape(-1, n_joints, 3))
    mean = so3.karcher_mean(poses)
    assert np.allclose(mean, mu, atol=1e-10)
    model = fit_pga(poses, np.arange(n_joints), k=2)
    # the two directions span the true plane, ordered by variance, and carry all the variance
    assert np.allclose(np.abs(model.basis.T @ v), np.eye(2), atol=1e-8)
    assert model.explained()[1] == pytest.approx(1.0, abs=1e-10)
    assert model.variance[0] / model.variance[1] == pytest.approx(25.0, rel=1e-8)


def test_logs_about_a_mean_in_steps_are_the_one_step_logs() -> None:
    """The logs about a mean taken a few hundred samples at a time (small temporaries) are the bits of the logs of
    every sample at once, of every column or of some."""
    rng = np.random.default_rng(5)
    n = 3 * so3.MEAN_ROWS + 17
    poses = so3.exp(rng.normal(scale=0.7, size=(n, 6, 3)))
    mean = so3.exp(rng.normal(size=(6, 3)))
    mt = np.swapaxes(mean, -1, -2)[None]
    active = np.array([0, 2, 5])
    assert np.array_equal(so3.log_between(mean, poses), so3.log(mt @ poses))
    assert np.array_equal(so3.log_between(mean[active], poses, active), so3.log(mt[:, active] @ poses[:, active]))


def test_exact_reconstruction_with_all_geodesics(run_clip: mocapz.Motion) -> None:
    m = run_clip.slice(1, 60)
    p = prepare(m, outliers=[])
    dim = p.full_model.basis.shape[1]
    s = PGASettings(k=dim, lod_root=0, lod_effectors=0, lod_coords=0, pos_step=1e-7, rot_step=1e-8,
                    coord_step=1e-8, basis_bits=24, mean_step=1e-9, iterations=2)
    sections = encode_prepared(p, s)
    from mocapz.codecs.pga.decode import decode_channels

    ch = decode_channels(m.skeleton, PGASettings.from_bytes(sections["params"]), sections, m.n_frames)
    a, b = m.positions(), forward_kinematics(m.skeleton, ch)[0]
    assert np.abs(a - b).max() < 1e-4  # file units (about 5 micrometres)


def test_ik_jacobian_matches_finite_differences(run_clip: mocapz.Motion) -> None:
    m = run_clip.slice(1, 30)
    sk = m.skeleton
    rot = local_rotations(sk, m.channels)
    inner = inner_joints(sk)
    model = fit_pga(rot[:, inner], inner, k=8)
    prob = IKProblem(sk, model, find_effectors(sk), np.broadcast_to(np.eye(3), (sk.n_joints, 3, 3)),
                     local_translations(sk, m.channels), 30.0)
    x = model.project(rot[:, inner])
    jac = prob.jacobian(*prob.forward(x))
    eps = 1e-6
    for c in range(model.k):
        dx = np.zeros(model.k)
        dx[c] = eps
        num = (prob.forward(x + dx)[0] - prob.forward(x - dx)[0]) / (2 * eps)
        assert np.abs(jac[..., c] - num).max() < 1e-6 * max(1.0, np.abs(num).max())


def test_ik_reaches_reachable_targets_and_stays_finite_otherwise(run_clip: mocapz.Motion) -> None:
    m = run_clip.slice(1, 40)
    sk = m.skeleton
    rot = local_rotations(sk, m.channels)
    inner = inner_joints(sk)
    model = fit_pga(rot[:, inner], inner, k=10)
    eff = find_effectors(sk)
    prob = IKProblem(sk, model, eff, np.broadcast_to(np.eye(3), (sk.n_joints, 3, 3)), sk.offsets, 30.0)
    x_true = model.project(rot[:, inner])
    targets = prob.forward(x_true)[0]
    start = x_true + np.random.default_rng(0).normal(0.0, 0.05, x_true.shape)
    x = solve(prob, targets, start, iterations=40, lam_temporal=0.0)
    assert np.abs(prob.forward(x)[0] - targets).max() < 0.01
    far = targets + 1e4  # far out of reach: a valid (finite) pose must come back anyway
    x_far = solve(prob, far, np.zeros_like(x_true), iterations=10)
    assert np.isfinite(x_far).all()


@pytest.mark.parametrize("lod", [0, 3])
def test_lifting_round_trip(run_clip: mocapz.Motion, lod: int) -> None:
    x = run_clip.channels[1:, :3]
    q, recon = lifting.encode_rn(x, 1e-3, lod)
    assert q.shape[0] == lifting.coefficient_rows(len(x), lod)
    assert np.array_equal(lifting.decode_rn(q, len(x), 1e-3, lod), recon)
    if lod == 0:
        assert np.abs(recon - x).max() <= 0.5e-3 + 1e-12
    r = local_rotations(run_clip.skeleton, run_clip.channels[1:])[:, 0]
    q, recon = lifting.encode_so3(r, 1e-5, lod)
    assert np.allclose(lifting.decode_so3(q, len(r), 1e-5, lod), recon, atol=1e-12)
    if lod == 0:
        err = np.linalg.norm(so3.log(np.swapaxes(recon, -1, -2) @ r), axis=-1)
        assert err.max() < 1e-4


@pytest.mark.slow
def test_acceptance_09_06_rate_control(run_clip: mocapz.Motion) -> None:
    data = mocapz.compress(run_clip, codec="pga", max_distortion=0.36, hold_feet=False)  # the paper's point
    back = mocapz.decompress(data)
    rep = mocapz.evaluate(run_clip, back)
    assert rep.distortion_pct <= 0.36
    assert run_clip.raw_bytes / len(data) >= 18
    assert np.isfinite(back.channels).all()


@pytest.mark.parametrize(("clip", "frames", "target"), [
    ("cmu/bvh/02_01.bvh", 240, {"max_error": "3cm"}),
    ("cmu/bvh/05_02.bvh", 240, {"max_distortion": 1.0}),
])
@pytest.mark.slow
def test_rate_control_meets_targets(clip: str, frames: int, target: dict) -> None:
    m = mocapz.load(data_path(clip)).slice(0, frames)
    back = mocapz.decompress(mocapz.compress(m, codec="pga", **target))
    rep = mocapz.evaluate(m, back)
    if "max_error" in target:
        assert rep.max_err_cm <= 3.0 + 1e-9
    else:
        assert rep.distortion_pct <= target["max_distortion"]


def test_deterministic_and_cgspeed_tpose_coded_apart(run_clip: mocapz.Motion) -> None:
    a = mocapz.compress(run_clip, codec="pga", geodesics=8)
    assert a == mocapz.compress(run_clip, codec="pga", geodesics=8)
    back = mocapz.decompress(a)
    # frame 0 (the added T-pose) comes back exactly at the file's precision
    assert np.allclose(back.channels[0], run_clip.channels[0], atol=1e-9)


def test_editing_moves_one_effector_and_keeps_the_others(run_clip: mocapz.Motion) -> None:
    data = mocapz.compress(run_clip, codec="pga", geodesics=20)
    traj = effector_trajectories(data)
    name = "LeftToeBase_End"
    lifted = traj[name].copy()
    lifted[40:80, 1] += 10.0 / run_clip.skeleton.unit_cm  # 10 cm up (Y is up in cgspeed BVH)
    edited = edit(data, {name: lifted})
    baseline = edit(data, {})
    names = run_clip.skeleton.point_names
    pe, pb = edited.positions(), baseline.positions()
    cm = run_clip.skeleton.unit_cm
    moved = np.linalg.norm(pe[:, names.index(name)] - lifted, axis=1)
    assert moved.max() * cm <= 0.5
    for other in traj:
        if other != name:
            drift = np.linalg.norm(pe[:, names.index(other)] - pb[:, names.index(other)], axis=1)
            assert drift.max() * cm <= 0.5, other
    with pytest.raises(OptionError):
        edit(data, {"Hips": lifted})


@pytest.mark.parametrize("options", [
    {"geodesics": 500}, {"geodesics": 0}, {"lod_root": -1}, {"lod_effectors": -2}, {"bogus": 1},
    {"max_error": "3 parsecs"}, {"effectors": "NoSuchJoint"},
])
def test_bad_parameters(run_clip: mocapz.Motion, options: dict) -> None:
    with pytest.raises(OptionError):
        mocapz.compress(run_clip.slice(0, 40), codec="pga", **options)


def test_impossible_target(run_clip: mocapz.Motion) -> None:
    with pytest.raises(TargetError):
        mocapz.compress(run_clip.slice(0, 40), codec="pga", max_distortion=1e-9)


@pytest.mark.parametrize("frames", [0, 1, 5])
def test_small_skeleton_short_clips_decode(frames: int) -> None:
    """A 3-joint skeleton (6-dimensional pose): a 0-frame clip keeps the default 12 geodesics, which the
    decoder's checks of the stored settings must not take for damage (they apply to kept frames only)."""
    rot = ("Zrotation", "Xrotation", "Yrotation")
    sk = Skeleton(names=["r", "a", "b"], parents=np.array([-1, 0, 1]),
                  offsets=np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]]),
                  channels=[("Xposition", "Yposition", "Zposition", *rot), rot, rot], rotation_order=["ZXY"] * 3,
                  end_sites=[(2, np.array([0.0, 1.0, 0.0]), "tip")])
    motion = mocapz.Motion(sk, np.random.default_rng(0).normal(size=(frames, 12)), 30.0)
    back = mocapz.decompress(mocapz.compress(motion, codec="pga"))
    assert back.channels.shape == (frames, 12)
