"""The correction's choice between bases on a long clip (:func:`mocapz.codecs.correction.search.search_bases`):
a base whose own bytes alone reach another base's predicted total is never tried on the windows (it cannot be the
smaller), the others are, at the lifting depth searched on the base of the fewest bytes of its own."""

from __future__ import annotations

import pytest
from conftest import data_path

import mocapz
from mocapz.codecs.correction import search
from mocapz.codecs.correction.fit import Clip
from mocapz.codecs.target import Target


@pytest.fixture(scope="module")
def clip() -> Clip:
    m = mocapz.load(data_path("cmu/bvh/06_13.bvh")).slice(0, 2400)  # over three 6-s windows: a long clip
    return Clip(m, True)


def _counting(monkeypatch: pytest.MonkeyPatch) -> list[tuple[int, float, int]]:
    calls: list[tuple[int, float, int]] = []  # (frames of the base, its first value, depth) of each fit
    real = search.bound_search

    def counted(clip, base, target, relax_by, depth, **kw):  # noqa: ANN001, ANN003, ANN202
        calls.append((base.shape[0], float(base.flat[0]), depth))
        return real(clip, base, target, relax_by, depth, **kw)

    monkeypatch.setattr(search, "bound_search", counted)
    return calls


def test_a_base_dearer_than_the_others_whole_prediction_is_not_tried(clip: Clip,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    zero = clip.zero_base()
    model = zero + 0.25  # another base: the correction's values shifted (its own bytes said huge below)
    calls = _counting(monkeypatch)
    target = Target(max_error=1.0 / clip.motion.unit_cm)
    best, cor = search.search_bases(clip, [model, zero], [10**9, 0], target)
    assert best == 1 and target.met(cor.errors)
    assert calls and all(first == float(zero.flat[0]) for _, first, _ in calls)  # the dear base: no fit at all
    windows = [c for c in calls if c[0] < clip.motion.n_frames]
    assert sorted({d for _, _, d in windows}) == sorted({max(1, clip.levels + d) for d in search.DEPTHS})


def test_bases_that_may_win_are_tried_at_the_depth_the_cheapest_chose(clip: Clip,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    zero = clip.zero_base()
    model = zero + 0.25
    calls = _counting(monkeypatch)
    target = Target(max_error=1.0 / clip.motion.unit_cm)
    best, _ = search.search_bases(clip, [model, zero], [40, 0], target)
    depths = {max(1, clip.levels + d) for d in search.DEPTHS}
    windows = [(first, d) for n, first, d in calls if n < clip.motion.n_frames]
    assert {d for first, d in windows if first == float(zero.flat[0])} == depths  # the cheapest: every depth
    assert len({d for first, d in windows if first == float(model.flat[0])}) == 1  # the other: the one it chose
    assert best in (0, 1)
