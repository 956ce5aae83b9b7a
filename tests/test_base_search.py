"""The correction's choice between bases (:func:`mocapz.codecs.correction.search.search_bases`): on a long clip
a base whose own bytes alone reach another base's predicted total is never tried on the windows (it cannot be the
smaller), the others are, at the lifting depth searched on the base of the fewest bytes of its own; a short clip's
bases, searched whole, go from the cheapest as well."""

from __future__ import annotations

from dataclasses import replace

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


@pytest.fixture(scope="module")
def short() -> Clip:
    return Clip(mocapz.load(data_path("cmu/bvh/12_01.bvh")).slice(0, 400), True)  # searched whole


def test_a_short_clips_bases_go_from_the_cheapest(short: Clip, monkeypatch: pytest.MonkeyPatch) -> None:
    """On a short clip (each base searched whole), the base of the fewest bytes of its own is searched first, at
    every depth, whatever the order it is given in; one that may win is searched at the depth it chose; one whose
    own bytes reach its total is not fitted (before, the first base given chose the depth for all: patterns took
    the zero base at its model's depth, 9,554 B on test_mocapbank.bvh where quant wrote 6,348)."""
    zero = short.zero_base()
    model = zero + 0.25
    target = Target(max_error=1.0 / short.motion.unit_cm)
    depths = {max(1, short.levels + d) for d in search.DEPTHS}
    calls = _counting(monkeypatch)
    best, cor = search.search_bases(short, [model, zero], [40, 0], target)
    assert {d for n, first, d in calls if first == float(zero.flat[0])} == depths
    assert len({d for n, first, d in calls if first == float(model.flat[0])}) == 1  # at the depth it chose
    assert calls[0][1] == float(zero.flat[0])  # the cheapest first, though given second
    calls.clear()
    best, cor = search.search_bases(short, [model, zero], [10**9, 0], target)
    assert best == 1 and target.met(cor.errors)
    assert calls and all(first == float(zero.flat[0]) for _, first, _ in calls)  # the dear base: no fit at all


def test_patterns_on_a_short_clip_is_no_larger_than_its_correction_alone() -> None:
    """The user's view: on a short real clip the codec with a model base (patterns) writes no more than the
    correction alone would (quant's zero base and the same correction: a few bytes of header apart)."""
    m = mocapz.load(data_path("other/bvh/bvh-python/test_mocapbank.bvh"))
    patterns = mocapz.compress(m, "patterns", max_error="1cm")
    quant = mocapz.compress(m, "quant", max_error="1cm")
    assert len(patterns) <= len(quant) + 16, (len(patterns), len(quant))


def _coded_nodes(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    from mocapz.codecs.patterns import bodies

    calls: list[int] = []
    real = bodies.code_node

    def counted(*args, **kw):  # noqa: ANN002, ANN003, ANN202
        calls.append(1)
        return real(*args, **kw)

    monkeypatch.setattr(bodies, "code_node", counted)
    return calls


@pytest.mark.parametrize(("name", "frames", "early"), [("cmu/bvh/02_05.bvh", 1855, True),
                                                        ("cmu/bvh/06_13.bvh", 3000, True),
                                                        ("cmu/bvh/09_06.bvh", 142, True),
                                                        ("cmu/c3d/01_01.c3d", 1200, True)])
def test_a_model_is_given_up_once_its_bytes_reach_the_correction_alones(name: str, frames: int, early: bool,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """The patterns model is encoded only as far as it may give the smaller file: where its own sections reach
    what the correction alone codes the clip in, its encoding stops (02_05's model is 2.4 times the correction
    alone's file; 06_13's first 3,000 frames 1.1 times, and 09_06's: each after the first of its five body parts,
    whose bytes the other four, each as large, would take past it); the
    file is byte for byte the one of a model encoded whole (the budget off), whichever base wins. A marker clip
    with gaps (01_01.c3d: its zero base has bytes of
    its own, the gap mask) at effort fast likewise: the depth is given, so the order the bases are tried in
    changes only what is made."""
    from mocapz.codecs import budget

    m = mocapz.load(data_path(name))
    m = m.slice(0, frames) if hasattr(m, "skeleton") else replace(m, positions=m.positions[:frames].copy())
    calls = _coded_nodes(monkeypatch)
    given_up = mocapz.compress(m, "patterns")
    parts = len(calls)
    calls.clear()
    spent: list[int] = []
    real = budget.spend

    def unlimited(payloads, left=0, least=0):  # noqa: ANN001, ANN202, ARG001  (the cap itself, not the estimate)
        try:
            real(payloads)
        except budget.OverBudget as over:
            spent.append(over.spent)

    monkeypatch.setattr(budget, "spend", unlimited)
    whole = mocapz.compress(m, "patterns")
    assert given_up == whole
    model_won = len(whole) <= len(mocapz.compress(m, "quant"))
    assert bool(spent) != model_won  # given up exactly where the correction alone is the smaller
    assert (parts < len(calls)) == early
    assert parts == (1 if early else len(calls))  # the first node's bytes are the estimate (bodies.MEASURED)


def test_a_budget_gives_up_where_the_parts_left_would_reach_its_cap() -> None:
    """:func:`budget.spend` raises where the bytes written and the parts left, each as large as the given smallest
    part, reach the cap; :class:`budget.OverBudget` carries the bytes written (a lower bound), not the estimate;
    outside :func:`budget.capped` nothing is counted."""
    from mocapz.codecs import budget

    written = [b"x" * (100 - budget.SECTION_OVERHEAD)]  # 100 bytes as sections count them
    budget.spend(written, left=1000, least=1000)  # no cap
    with budget.capped(300):
        budget.spend(written, left=3, least=66)  # 100 + 198 < 300
        with pytest.raises(budget.OverBudget) as over:
            budget.spend(written, left=4, least=50)  # 100 + 200 reaches 300
        assert over.value.spent == 100
        with pytest.raises(budget.OverBudget):
            budget.spend(written * 3)  # 300 written
