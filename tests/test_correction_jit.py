"""The compiled kernels of the correction's closed loop (:mod:`mocapz.codecs.correction.chainkernels`) give what
the NumPy path gives: the same integers and decoded residual, positions to float rounding, on real skeletons of
each kind (CMU BVH, an ASF with joint axes, the iClone rig with its tiny bones), and the same file."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import correction_case, data_path

import mocapz
from mocapz.codecs.correction import bounds, chain, compiled, context, lifting, wrap
from mocapz.codecs.correction.fit import Clip
from mocapz.codecs.pga import ikjit

pytest.importorskip("numba")

CLIPS = [("cmu/bvh/06_10.bvh", 700), ("cmu/asfamc/backflip.amc", None), ("other/asfamc/amcparser/walking.amc", 600),
         ("cmu/bvh_iclone_ccrig/002_03.bvh", None)]


@pytest.fixture
def kernels_always(monkeypatch: pytest.MonkeyPatch) -> None:
    """The kernels whatever the clip's length (numpy below :data:`compiled.LAZY_FRAMES` otherwise)."""
    monkeypatch.setattr(compiled, "LAZY_FRAMES", 0)
    monkeypatch.setattr(compiled, "LAZY_DECODE_FRAMES", 0)


def _quantise(clip: Clip, tol: np.ndarray, compiled: bool, prefix: np.ndarray | None = None,
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    old = ikjit.set_enabled(compiled)
    try:
        assert clip.chain is not None
        assert (chain.kernels(clip.motion.n_frames) is not None) == compiled
        base = np.zeros_like(clip.values)
        return clip.chain.quantise(clip.residual(base), base, tol, 3, 0.85, prefix)
    finally:
        ikjit.set_enabled(old)


@pytest.mark.parametrize("continued", [False, True])
@pytest.mark.parametrize(("rel", "frames"), CLIPS)
def test_kernels_equal_numpy(rel: str, frames: int | None, continued: bool, kernels_always: None) -> None:
    """Also for a continued block: the frames before it (the clip's own, a little off) give its first knots and
    its ghosts (:func:`~.context.prefix`), which the one-call round (:mod:`.roundkernels`) reads as NumPy does."""
    clip, t0, levels = correction_case(rel, frames, 16, 7, 4)
    lay = clip.layout
    tol = bounds.tolerances(t0, lay, levels)
    prefix = None
    if continued:
        before = clip.values[::-1][:40] + np.random.default_rng(1).normal(scale=0.01, size=(40, clip.values.shape[1]))
        prefix = context.prefix(before, clip.rot, clip.period, True)
    qa, ya, pa = _quantise(clip, tol, True, prefix)
    qb, yb, pb = _quantise(clip, tol, False, prefix)
    assert np.array_equal(qa, qb)
    assert np.array_equal(ya, yb)
    scale = float(np.abs(pb).max())
    assert np.abs(pa - pb).max() <= 1e-12 * scale
    # and the positions are those of forward kinematics on the decoded values
    assert np.abs(pa - clip.positions_of(ya)).max() <= 1e-12 * scale


def test_same_file_either_path(kernels_always: None) -> None:
    m = mocapz.load(data_path("cmu/bvh/09_06.bvh"))
    old = ikjit.set_enabled(False)
    try:
        plain = mocapz.compress(m, codec="quant", max_error="1cm")
    finally:
        ikjit.set_enabled(old)
    assert mocapz.compress(m, codec="quant", max_error="1cm") == plain


@pytest.mark.parametrize("seed", range(4))
def test_lifting_kernel_gives_the_numpy_bits(seed: int) -> None:
    """:mod:`.liftkernels` codes the details with the NumPy path's float operations in its order: the same
    integers and decoded residual to the bit, on smooth and flat residuals, free columns and every depth."""
    rng = np.random.default_rng(seed)
    for _ in range(40):
        frames, cols, depth = int(rng.integers(1, 600)), int(rng.integers(1, 7)), int(rng.integers(0, 7))
        x = np.cumsum(rng.normal(size=(frames, cols)), axis=0) * float(rng.choice([0.01, 1.0, 100.0]))
        x[: int(rng.integers(0, frames + 1))] = 0.0
        tol = rng.uniform(0.01, 2.0, size=(frames, cols))
        tol[:, 0] = lifting.BIG if rng.random() < 0.3 else tol[:, 0]
        shrink = float(rng.choice([1.0, 0.85, 0.7]))
        qa, ya = lifting.quantise(x, tol, depth, shrink, compiled=True)
        qb, yb = lifting.quantise(x, tol, depth, shrink, compiled=False)
        assert np.array_equal(qa, qb)
        assert np.array_equal(ya, yb)
        assert np.array_equal(lifting.decode(qa, tol, depth, shrink), ya)


@pytest.mark.parametrize("seed", range(3))
def test_a_continued_lifting_gives_the_numpy_bits(seed: int, kernels_always: None) -> None:
    """A continued clip's lifting (a stream's block: the first knot from the frame before, the levels' first
    details predicted across the edge from the ghosts, some NaN) coded and decoded by the kernels
    (:func:`~.liftkernels.details`, :func:`~.liftkernels.decode_details`) gives the NumPy path's bits."""
    rng = np.random.default_rng(seed)
    for _ in range(30):
        frames, cols, depth = int(rng.integers(2, 300)), int(rng.integers(1, 6)), int(rng.integers(1, 7))
        x = np.cumsum(rng.normal(size=(frames, cols)), axis=0)
        prefix = np.full((cols, 1 + context.GHOST_LEVELS), np.nan)
        prefix[:, 0] = x[0] + rng.normal(size=cols)
        reach = int(rng.integers(0, context.GHOST_LEVELS + 1))
        prefix[:, 1:1 + reach] = x[0][:, None] + rng.normal(size=(cols, reach))
        prefix[rng.random(prefix.shape) < 0.1] = np.nan
        groups = np.arange(cols)
        lev = rng.integers(0, 6, size=(frames, cols))
        tol_col = rng.uniform(0.05, 1.0, size=cols)
        tol = tol_col[None, :] * wrap.HALVES[lev]
        qa, ya = lifting.quantise(x, tol, depth, 0.85, compiled=True, prefix=prefix)
        qb, yb = lifting.quantise(x, tol, depth, 0.85, compiled=False, prefix=prefix)
        assert np.array_equal(qa, qb)
        assert np.array_equal(ya, yb)
        assert np.array_equal(lifting.decode(qa, tol, depth, 0.85, prefix=prefix), ya)  # NumPy
        assert np.array_equal(lifting.decode_table(qa, tol_col, wrap.HALVES, lev, groups, depth, 0.85, prefix), ya)


@pytest.mark.parametrize(("rel", "frames"), CLIPS)
def test_rounds_redo_only_what_moved(rel: str, frames: int | None, kernels_always: None) -> None:
    """A call on the same residual and base after another (a fit's rounds: tolerances tightened on a few
    frames) redoes only the frames where a decoded value above a joint moved, and gives to the bit what a
    call from scratch gives."""
    m = mocapz.load(data_path(rel))
    m = m if frames is None else m.slice(0, frames)
    clip = Clip(m, True)
    assert clip.chain is not None
    lay = clip.layout
    e = 1.0 / m.unit_cm if m.unit_cm else clip.body / 170.0
    t0 = bounds.tol_of(bounds.code_for(np.where(lay.moving, 16 * lay.t_safe * e, bounds.TINY * lay.t_safe * e)))
    rng = np.random.default_rng(3)
    levels = rng.integers(0, 3, size=(m.n_frames, lay.n_groups))
    base = np.zeros_like(clip.values)
    x = clip.residual(base)
    clip.chain.quantise(x, base, bounds.tolerances(t0, lay, levels), 4, 0.85)
    for _ in range(4):
        for f in rng.integers(0, m.n_frames, size=5):  # a round tightens a few frames of a few groups
            levels[max(0, f - 3) : f + 3, rng.integers(0, lay.n_groups)] += 1
        tol = bounds.tolerances(t0, lay, levels)
        assert clip.chain.last is not None and clip.chain.last.x is x
        qa, ya, pa = clip.chain.quantise(x, base, tol, 4, 0.85)
        clip.chain.forget()
        qb, yb, pb = clip.chain.quantise(x, base, tol, 4, 0.85)
        assert np.array_equal(qa, qb)
        assert np.array_equal(ya, yb)
        assert np.array_equal(pa, pb)


def test_a_block_of_a_long_clip_loads_the_kernels() -> None:
    """A block is short, but the job is its whole clip: the compiled kernels pay for loading there, so the
    block's closed loop uses them as the whole clip's would (the NumPy path below LAZY_FRAMES is for short jobs)."""
    from dataclasses import replace

    from mocapz.model.motion import BlockOf

    m = mocapz.load(data_path("cmu/bvh/06_13.bvh"))
    piece = m.slice(0, 120)
    piece = replace(piece, metadata={**piece.metadata, "block_of": BlockOf(m, 0, 120, {})})
    clip = Clip(piece, True)
    assert clip.chain is not None
    assert clip.work == clip.chain.work == m.n_frames
    assert chain.kernels(max(120, clip.chain.work)) is not None
