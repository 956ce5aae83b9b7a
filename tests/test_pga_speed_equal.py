"""The PGA decoder's compiled kernels (numba, ``codecs/pga/ikjit``) against its plain NumPy path: the same
IK coordinates and the same decoded channels, to float rounding, on real clips."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.codecs.pga import ikjit, iksolve
from mocapz.codecs.pga.params import PGASettings
from mocapz.format.container import Container
from mocapz.format.layout import decode_header

pytest.importorskip("numba")

pga_decode = importlib.import_module("mocapz.codecs.pga.decode")  # the module (the package exports a function)

CLIPS = [("09_06", None), ("02_03", None), ("12_01", 300), ("06_13", 400), ("01_01", 300)]  # 01_01: ASF/AMC


@pytest.fixture(autouse=True)
def _compiled_on_short_clips(monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled path on these short clips too (the decoder takes the NumPy path under ikjit.LAZY_FRAMES)."""
    monkeypatch.setattr(ikjit, "LAZY_FRAMES", 0)


@pytest.fixture(scope="module")
def coded() -> dict[str, bytes]:
    out = {}
    for name, stop in CLIPS:
        m = mocapz.load(data_path(f"cmu/asfamc/{name}.amc" if name == "01_01" else f"cmu/bvh/{name}.bvh"))
        if stop:
            m = m.slice(0, stop)
        out[name] = mocapz.compress(m, codec="pga", geodesics=12, lod_root=1, lod_effectors=1)
    return out


def _both(fn):  # noqa: ANN001, ANN202
    """``fn()`` on the NumPy path, then on the compiled one."""
    old = ikjit.set_enabled(False)
    try:
        plain = fn()
        ikjit.set_enabled(True)
        assert ikjit.kernels() is not None
        fast = fn()
    finally:
        ikjit.set_enabled(old)
    return plain, fast


@pytest.mark.parametrize("name", [c[0] for c in CLIPS])
@pytest.mark.parametrize("iterations", [1, 2, 6])
def test_ik_coordinates_equal(coded: dict[str, bytes], name: str, iterations: int) -> None:
    box = Container.from_bytes(coded[name])
    header = decode_header(box.layout)
    s = PGASettings.from_bytes(box.sections["params"])
    d = pga_decode.decode_streams(header.skeleton, s, box.sections, header.frames - len(s.outliers))

    def run() -> np.ndarray:
        return iksolve.solve_fast(d.problem, d.targets, d.coords, x_prior=d.coords, lam_temporal=0.0,
                                  lam_prior=s.lam_prior, iterations=iterations)

    plain, fast = _both(run)
    diff = np.abs(plain - fast).max(axis=1)
    if iterations <= PGASettings().iterations:  # the decoder's own count: rounding apart
        assert diff.max() < 1e-12
    else:  # steps taken or refused near convergence may move a badly conditioned frame a little further
        assert np.median(diff) < 1e-14 and diff.max() < 1e-6
    assert np.abs(plain - d.coords).max() > 1e-6  # the IK did move the coordinates


@pytest.mark.parametrize("name", [c[0] for c in CLIPS])
def test_decoded_channels_equal(coded: dict[str, bytes], name: str) -> None:
    plain, fast = _both(lambda: mocapz.decompress(coded[name]).channels)
    assert plain.shape == fast.shape
    assert np.allclose(plain, fast, rtol=0, atol=1e-9)


def test_euler_kernel_is_used_on_bvh_and_amc() -> None:
    from mocapz.codecs.pga.channels import euler_tables
    from mocapz.codecs.pga.joints import inner_joints

    for rel in ("cmu/bvh/09_06.bvh", "cmu/asfamc/01_01.amc"):
        sk = mocapz.load(data_path(rel)).skeleton
        tables = euler_tables(sk, np.asarray(inner_joints(sk)))
        assert tables is not None
        assert tables[5].any() == (rel.endswith(".amc"))  # ASF axis frames turn the rotations


def test_pose_equal(coded: dict[str, bytes]) -> None:
    box = Container.from_bytes(coded["02_03"])
    header = decode_header(box.layout)
    s = PGASettings.from_bytes(box.sections["params"])
    d = pga_decode.decode_streams(header.skeleton, s, box.sections, header.frames - len(s.outliers))
    plain, fast = _both(lambda: iksolve.pose(d.model, d.coords))
    assert np.allclose(plain, fast, rtol=0, atol=1e-14)


def test_disabled_kernels_give_none() -> None:
    old = ikjit.set_enabled(False)
    try:
        assert ikjit.kernels() is None
    finally:
        ikjit.set_enabled(old)
