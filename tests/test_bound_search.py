"""The correction's bound search for a distortion or ARMS target: where the base's own errors already meet the target
(a good model), the target's figure hardly grows with the bound, and the search goes straight to the largest bound
allowed instead of creeping up to it a secant step at a time."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
import mocapz.codecs.correction.search as search_module
from mocapz.codecs.correction.fit import Clip
from mocapz.codecs.correction.search import LOOSEST, _flat


def test_a_figure_growing_with_the_bound_is_not_flat() -> None:
    assert not _flat((0.5, 0.4), (1.0, 0.8))  # proportional
    assert not _flat((1.0, 0.8), (0.5, 0.4))  # either order
    assert not _flat((0.5, 0.4), (0.6, 0.4 * 1.2 ** 0.5))  # half as fast: still the bound's doing
    assert _flat((0.5, 0.40), (0.6, 0.401))  # the base's own errors
    assert _flat((0.6, 0.41), (0.5, 0.40))
    assert not _flat((0.5, 0.4), (0.5, 0.4))  # one bound: nothing measured


def _fits(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """The bounds the search fits at, in order."""
    bounds: list[float] = []
    real = search_module.fit

    def counted(clip: Clip, base: np.ndarray, e: float, *args: object, **kwargs: object):  # noqa: ANN202
        bounds.append(e)
        return real(clip, base, e, *args, **kwargs)

    monkeypatch.setattr(search_module, "fit", counted)
    return bounds


def test_a_model_meeting_the_target_alone_is_searched_in_a_few_fits(monkeypatch: pytest.MonkeyPatch) -> None:
    """PGA on 02_05 at max ARMS 5 mm: the model's own errors meet it (its ARMS about 0.07 cm whatever the bound).
    The correction's search stops at the largest bound allowed (LOOSEST times the model's largest error) in at most
    five fits, where the secant's steps alone creep there over more (the file: smaller than the model's bytes
    tell, decoded within the target)."""
    m = mocapz.load(data_path("cmu/bvh/02_05.bvh"))
    bounds = _fits(monkeypatch)
    data = mocapz.compress(m, "pga", max_arms="5mm")
    fast = list(bounds)
    assert 2 <= len(fast) <= 5 and fast[-1] == pytest.approx(LOOSEST * fast[0])  # the first: the model's largest
    report = mocapz.evaluate(m, mocapz.decompress(data))
    assert report.arms * report.unit_cm <= 0.5 + 1e-9  # 5 mm (the report's figures are in file units)
    monkeypatch.setattr(search_module, "_flat", lambda *_: False)  # the shortcut off: the secant's steps alone
    bounds.clear()
    mocapz.compress(m, "pga", max_arms="5mm")
    assert len(bounds) > len(fast) + 3
