"""A stream's block meets the block before it without a kink: its lifting's first details are predicted across
the edge from the decoded frames before it (``c.head`` format 5, :func:`mocapz.codecs.correction.context.prefix`),
as inside a clip, instead of from its first knot alone (format 4)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz import blocking
from mocapz.codecs.correction import context, fit, lifting


def test_the_frames_before_reach_every_ghost() -> None:
    """The decoded frames a continued block is given (:data:`mocapz.blocking.BEFORE_FRAMES`, which knows no codec)
    reach the ghost of the deepest lifting any clip takes (:func:`.fit.lifting_levels`, 6 levels at 256 fps and
    above): ``2 ** 6`` frames before the first knot."""
    assert context.GHOST_LEVELS >= fit.lifting_levels(1e6)
    assert blocking.BEFORE_FRAMES >= 1 + 2 ** context.GHOST_LEVELS


def _added(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Acceleration energy (squared second differences) decoded ``y`` adds to ``x``, per frame."""
    return ((y[2:] - 2.0 * y[1:-1] + y[:-2]) ** 2 - (x[2:] - 2.0 * x[1:-1] + x[:-2]) ** 2).sum(axis=1)


def test_a_continued_lifting_meets_the_clip_before_it_smoothly() -> None:
    """Smooth curves (sines of random periods, 3 to 12 frames per radian) cut in two, the second part continued
    from the first's decoded frames: with the ghosts the acceleration energy the coding adds at the cut is under
    0.75 of what it adds from the first knot alone (measured 0.63), and no more in all; both within the tolerance
    and decoded to the same numbers."""
    rng = np.random.default_rng(0)
    edge = {False: 0.0, True: 0.0}
    total = {False: 0.0, True: 0.0}
    for _ in range(200):
        frames, cut = 96, 32 * int(rng.integers(1, 3))
        t = np.arange(frames)[:, None]
        x = np.sin(t / rng.uniform(3, 12, size=4) + rng.uniform(0, 6, size=4)) * rng.uniform(0.5, 5, size=4)
        tol = np.full_like(x, float(rng.uniform(0.2, 1.0)))
        _, ya = lifting.quantise(x[:cut], tol[:cut], 3, 1.0, compiled=False)
        for ghosts in (False, True):
            pre = context.prefix(ya, np.zeros(4, dtype=bool), 0.0, ghosts)
            qb, yb = lifting.quantise(x[cut:], tol[cut:], 3, 1.0, compiled=False, prefix=pre)
            assert np.array_equal(lifting.decode(qb, tol[cut:], 3, 1.0, prefix=pre), yb)
            y = np.concatenate([ya, yb])
            assert np.abs(y - x).max() <= tol.max() * (1 + 1e-9)
            added = _added(y, x)
            edge[ghosts] += added[cut - 2:cut + 1].sum()  # the second differences taking in the frame before
            total[ghosts] += added.sum()
    assert edge[True] <= 0.75 * edge[False]
    assert total[True] <= total[False]


def _stream(m: mocapz.AnyMotion, chunk: int = 37) -> bytes:
    enc = mocapz.StreamEncoder(m, "quant")
    out = b"".join(enc.write(m.values[i:i + chunk]) for i in range(0, m.n_frames, chunk))
    return out + enc.close()


def test_a_30_fps_stream_pays_less_for_its_edges(monkeypatch: pytest.MonkeyPatch) -> None:
    """A slow 30-fps BVH streamed in 1-s blocks (32 frames): predicting across the edges makes the stream under
    0.85 of the same stream without (measured 7,291 against 9,751 B, 9,541 against 11,995 before the blocks'
    handover: the kink at every edge cost the jitter's tightening), its target met on every point."""
    m = mocapz.load(data_path("other/bvh/bvh-python/test_mocapbank.bvh"))
    across = _stream(m)
    real = context.prefix
    monkeypatch.setattr(context, "prefix", lambda before, rot, period, ghosts=False: real(
        np.atleast_2d(before)[-1], rot, period))
    alone = _stream(m)
    assert len(across) <= 0.85 * len(alone)
    monkeypatch.undo()
    assert mocapz.evaluate(m, mocapz.decompress(across)).max_err_cm <= 1.0 + 1e-9


def test_a_marker_stream_holds_its_jitter_across_its_edges() -> None:
    """Plug-in Gait markers at 100 fps (PiG_Motion-FlatFoot-Full.c3d, 96-frame blocks): the stream's added
    jitter within the correction's allowance (15.3 % before the edges were predicted across, 2.2 % now) and
    the stream within a fifth of the offline file (1.46 times before; 14,103 against 12,480 B now)."""
    m = mocapz.load(data_path("other/markers/btkdata/c3d_samples/PiG_Motion-FlatFoot-Full.c3d"))
    m.metadata.pop("c3d", None)
    data = _stream(m)
    rep = mocapz.evaluate(m, mocapz.decompress(data))
    assert rep.max_err_cm <= 1.0 + 1e-9 and rep.jitter_pct <= 4.5
    assert len(data) <= 1.2 * len(mocapz.compress(m, codec="quant"))


@pytest.mark.parametrize(("rel", "most"), [("other/bvh/bvh-python/test_mocapbank.bvh", 0.85),
                                           ("cmu/asfamc/11_01.amc", 0.9)])
def test_a_skeleton_stream_hands_its_blocks_over_near_the_original(monkeypatch: pytest.MonkeyPatch, rel: str,
                                                                   most: float) -> None:
    """A skeleton stream's block that the next one continues codes its last frame tighter
    (:data:`~mocapz.codecs.correction.fit.HANDOVER_LEVELS`): the next block starts near the original instead of
    pulling its first frames onto it. The stream is under ``most`` of the same stream handed over at the
    block's own tolerance (test_mocapbank.bvh 7,291 against 9,541 B; 11_01.amc 6,950 against 8,829), its target
    met on every point."""
    m = mocapz.load(data_path(rel))
    over = _stream(m)
    monkeypatch.setattr(fit, "HANDOVER_LEVELS", 0)
    plain = _stream(m)
    monkeypatch.undo()
    assert len(over) <= most * len(plain)
    assert mocapz.evaluate(m, mocapz.decompress(over)).max_err_cm <= 1.0 + 1e-9


def test_a_marker_stream_is_handed_over_at_its_own_tolerance(monkeypatch: pytest.MonkeyPatch) -> None:
    """Markers' errors stay on their own points: their blocks' last frames are not tightened (the tighter knot
    cost the shared marker files' streams 4.5 % more): the same bytes with or without the handover's levels."""
    m = mocapz.load(data_path("other/markers/btkdata/Gait.trc")).slice(0, 300)
    over = _stream(m)
    monkeypatch.setattr(fit, "HANDOVER_LEVELS", 0)
    assert _stream(m) == over
