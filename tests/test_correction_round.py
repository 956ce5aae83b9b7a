"""The closed loop's round in one compiled call (:mod:`mocapz.codecs.correction.chainround`) gives, to the bit, what
the per-joint loop of compiled kernels gives: the integers, the decoded residual and every joint and end site's
position, on real skeletons (CMU BVH, an ASF with joint axes, the iClone rig with its tiny bones), from scratch, on
a call redoing the one before, and on a continued block (a prefix with missing values); the file is the same."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import correction_case, data_path

import mocapz
from mocapz.codecs.correction import bounds, chainround, compiled
from mocapz.codecs.correction.fit import Clip

pytest.importorskip("numba")

CLIPS = [("cmu/bvh/06_10.bvh", 700), ("other/asfamc/amcparser/walking.amc", 600),
         ("cmu/bvh_iclone_ccrig/002_03.bvh", None), ("cmu/bvh/09_06.bvh", None),
         ("cmu/asfamc/backflip.amc", None), ("cmu/asfamc/01_01.amc", 500)]  # the last two: hinges


@pytest.fixture
def kernels_always(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(compiled, "LAZY_FRAMES", 0)
    monkeypatch.setattr(compiled, "LAZY_DECODE_FRAMES", 0)


def _clip(rel: str, frames: int | None) -> tuple[Clip, np.ndarray, np.ndarray]:
    return correction_case(rel, frames, 4, 5, 5)  # type: ignore[no-any-return]


def _both(clip: Clip, x: np.ndarray, base: np.ndarray, tol: bounds.ColumnTolerances, depth: int,
          prefix: np.ndarray | None = None) -> list[tuple[np.ndarray, ...]]:
    """The coding of one call with the one-call round and with the per-joint loop (copies; the chain forgets)."""
    assert clip.chain is not None
    plan, out = clip.chain.round_plan, []
    try:
        for use in (plan, None):
            clip.chain.round_plan = use
            xi = x.copy()
            out.append(tuple(a.copy() for a in clip.chain.quantise(xi, base, tol, depth, 0.85, prefix)) + (xi,))
            clip.chain.forget()
    finally:
        clip.chain.round_plan = plan
    return out


def _equal(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> None:
    for u, v in zip(a, b, strict=True):  # integers, decoded residual, positions, residual against the goals
        assert u.shape == v.shape
        assert np.array_equal(u, v)


@pytest.mark.parametrize(("rel", "frames"), CLIPS)
def test_one_call_round_gives_the_loops_bits(rel: str, frames: int | None, kernels_always: None) -> None:
    clip, t0, levels = _clip(rel, frames)
    assert clip.chain is not None and clip.chain.round_plan is not None
    base = np.zeros_like(clip.values)
    for depth in (0, 2, 5):
        x = clip.residual(base)
        assert chainround.usable(clip.chain, x, base, bounds.tolerances(t0, clip.layout, levels))
        _equal(*_both(clip, x, base, bounds.tolerances(t0, clip.layout, levels), depth))
    # a base that is not zero (a model's decoded values): every column's residual against it
    base = clip.values + np.random.default_rng(2).normal(0.0, 0.3, clip.values.shape)
    _equal(*_both(clip, clip.residual(base), base, bounds.tolerances(t0, clip.layout, levels), 3))


@pytest.mark.parametrize(("rel", "frames"), CLIPS[:2])
def test_continued_block(rel: str, frames: int | None, kernels_always: None) -> None:
    """A stream's block after another: the first knot is the prefix's (NaN: coded as in a clip of its own)."""
    clip, t0, levels = _clip(rel, frames)
    base = np.zeros_like(clip.values)
    prefix = clip.values[0] + 0.01
    prefix[::5] = np.nan
    _equal(*_both(clip, clip.residual(base), base, bounds.tolerances(t0, clip.layout, levels), 3, prefix))


@pytest.mark.parametrize("rotations_kept", [True, False])
def test_rounds_redone_on_what_moved_match(kernels_always: None, rotations_kept: bool,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Calls redoing the one before (tolerances tightened on a few frames) give the loop's bits too: with every
    joint's rotations kept from a call to the next (composed again only where they may have moved) and without
    (a clip over :data:`.chainround.KEPT_BYTES`)."""
    if not rotations_kept:
        monkeypatch.setattr(chainround, "KEPT_BYTES", 0)
    clip, t0, levels = _clip(*CLIPS[0])
    assert clip.chain is not None
    base = np.zeros_like(clip.values)
    runs, kept = [], clip.chain.round_plan
    assert kept is not None
    for plan in (kept, None):
        clip.chain.round_plan, lv = plan, levels.copy()
        x = clip.residual(base)
        rng, got, held = np.random.default_rng(11), [], []
        for _ in range(4):
            got.append(tuple(a.copy() for a in clip.chain.quantise(x, base, bounds.tolerances(t0, clip.layout, lv),
                                                                   4, 0.85)))
            held.append(None if clip.chain.last is None else clip.chain.last.rot)
            for f in rng.integers(0, len(lv), size=6):
                lv[max(0, f - 3): f + 3, rng.integers(0, lv.shape[1])] += 1
        clip.chain.forget()
        runs.append(got)
        if plan is not None:  # one array of rotations updated in place from call to call, or none
            assert all(h is held[0] for h in held) and (held[0] is not None) == rotations_kept
    clip.chain.round_plan = kept
    for a, b in zip(*runs, strict=True):
        _equal(a, b)


def test_where_the_loop_stays(kernels_always: None) -> None:
    """A NaN value or dense tolerances take the per-joint loop (ASF hinges take the one-call round: the cases
    above)."""
    clip, t0, levels = _clip(*CLIPS[0])
    assert clip.chain is not None
    base = np.zeros_like(clip.values)
    x = clip.residual(base)
    tol = bounds.tolerances(t0, clip.layout, levels)
    assert chainround.usable(clip.chain, x, base, tol)
    assert not chainround.usable(clip.chain, x, base, np.asarray(tol))
    x[5, 3] = np.nan
    assert not chainround.usable(clip.chain, x, base, tol)


def test_same_file_either_way(monkeypatch: pytest.MonkeyPatch) -> None:
    m = mocapz.load(data_path("cmu/bvh/02_05.bvh")).slice(0, 900)
    fused = mocapz.compress(m, codec="quant")
    monkeypatch.setattr(chainround, "plan", lambda chain: None)
    assert mocapz.compress(m, codec="quant") == fused
