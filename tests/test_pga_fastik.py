"""The decoder's fast IK (``codecs/pga/iksolve``) against the reference solver (``codecs/pga/ik.solve``):
same Jacobian, same coordinates to rounding, and a decoded clip no further from the original."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.codecs.pga import iksolve
from mocapz.codecs.pga.ik import solve
from mocapz.codecs.pga.params import PGASettings
from mocapz.format.container import Container
from mocapz.format.layout import decode_header

pga_decode = importlib.import_module("mocapz.codecs.pga.decode")  # the module (the package exports a function)

CLIPS = [("09_06", None), ("02_03", None), ("12_01", 300)]


@pytest.fixture(scope="module")
def coded() -> dict[str, tuple[mocapz.Motion, bytes]]:
    """Clip name -> (original motion, pga bytes at fixed settings)."""
    out = {}
    for name, stop in CLIPS:
        m = mocapz.load(data_path(f"cmu/bvh/{name}.bvh"))
        if stop:
            m = m.slice(0, stop)
        out[name] = (m, mocapz.compress(m, codec="pga", geodesics=12, lod_root=1, lod_effectors=1))
    return out


def _streams(data: bytes) -> tuple[pga_decode.Decoded, PGASettings]:
    box = Container.from_bytes(data)
    header = decode_header(box.layout)
    s = PGASettings.from_bytes(box.sections["params"])
    n = header.frames - len(s.outliers)
    return pga_decode.decode_streams(header.skeleton, s, box.sections, n), s


def test_spd_solve_equals_numpy() -> None:
    rng = np.random.default_rng(1)
    m = rng.normal(size=(40, 16, 16))
    a = m @ m.transpose(0, 2, 1) + 0.1 * np.eye(16)
    b = rng.normal(size=(40, 16))
    want = np.linalg.solve(a, b[..., None])[..., 0]
    got = iksolve.spd_solve(a.transpose(1, 2, 0).copy(), b.T.copy()).T
    assert np.allclose(got, want, rtol=1e-9, atol=1e-9)


def test_rodrigues_equals_so3() -> None:
    from mocapz.codecs.pga import so3

    w = np.random.default_rng(2).normal(size=(7, 50, 3))
    w[0, :5] *= 1e-6  # the small-angle branch
    r, jr = iksolve.rodrigues(w.transpose(0, 2, 1))
    assert np.allclose(r.transpose(0, 3, 1, 2), so3.exp(w), atol=1e-12)
    assert np.allclose(jr.transpose(0, 3, 1, 2), so3.right_jacobian(w), atol=1e-12)


def test_fast_jacobian_and_positions_equal_the_reference(coded: dict) -> None:
    d, _ = _streams(coded["09_06"][1])
    x = d.coords
    fast = iksolve.FastIK(d.problem)
    trans = d.problem.trans.transpose(1, 2, 0) if d.problem.trans.ndim == 3 else d.problem.trans
    state = fast.forward(x.T.copy(), trans)
    pos, g, o, w = d.problem.forward(x)
    assert np.allclose(state[0].transpose(2, 0, 1), pos, rtol=0, atol=1e-10)
    jac = fast.jacobian(*state)  # (e*3, k, F)
    ref = d.problem.jacobian(pos, g, o, w).reshape(x.shape[0], -1, x.shape[1])
    assert np.allclose(jac.transpose(2, 0, 1), ref, rtol=0, atol=1e-9 * np.abs(ref).max())


@pytest.mark.parametrize("lam_temporal", [0.0, 1e-3])
def test_fast_solver_equals_the_reference(coded: dict, monkeypatch: pytest.MonkeyPatch, lam_temporal: float) -> None:
    monkeypatch.setattr(iksolve, "BLOCK", 50)  # several blocks, the last one short
    for name, _ in CLIPS:
        d, s = _streams(coded[name][1])
        kw = {"x_prior": d.coords, "lam_temporal": lam_temporal, "lam_prior": s.lam_prior, "iterations": s.iterations}
        ref = solve(d.problem, d.targets, d.coords, **kw)
        fast = iksolve.solve_fast(d.problem, d.targets, d.coords, **kw)
        assert np.isfinite(fast).all()
        assert np.abs(fast - ref).max() < 1e-6  # radians; typically 1e-8 (LM steps accepted at the rounding edge)


def test_fast_decoder_is_no_further_from_the_original(coded: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    """Version 2 of the decoder (fast IK) against version 1's (the reference solver): max error and d."""
    for name, _ in CLIPS:
        original, data = coded[name]
        new = mocapz.evaluate(original, mocapz.decompress(data))
        with monkeypatch.context() as mp:
            mp.setattr(pga_decode, "solve_fast", lambda *a, frames=None, **kw: solve(*a, **kw))  # frames: the path
            old = mocapz.evaluate(original, mocapz.decompress(data))
        assert new.max_err <= old.max_err * (1 + 1e-6) + 1e-9, name
        assert new.distortion_pct <= old.distortion_pct * (1 + 1e-6) + 1e-9, name


def test_fast_pose_equals_the_model(coded: dict) -> None:
    d, _ = _streams(coded["02_03"][1])
    assert np.allclose(iksolve.pose(d.model, d.coords), d.model.pose(d.coords), rtol=0, atol=1e-13)
