"""A base whose correction cannot give the smaller file is given up after its first verification round, or after a
later one whose integers grew past the bytes: the same file, without the rounds that would only have confirmed it."""

from __future__ import annotations

import math
from typing import Any

import pytest
from conftest import data_path

import mocapz
from mocapz.codecs.correction import search
from mocapz.codecs.correction.fit import GAVE_UP, Clip, fit
from mocapz.codecs.correction.wrap import resolve_target
from mocapz.format.entropy import encode_int_matrix


def test_fit_gives_up_where_its_first_round_reaches_the_bytes() -> None:
    m = mocapz.load(data_path("cmu/bvh/09_06.bvh"))
    clip = Clip(m, True)
    e = resolve_target(m, {}).max_error
    whole = fit(clip, clip.zero_base(), e)
    assert whole.size < GAVE_UP and whole.sections and whole.errors.max_error <= e
    given_up = fit(clip, clip.zero_base(), e, give_up=1.0)  # any coding has more than one byte
    assert given_up.size == GAVE_UP and not given_up.sections and math.isinf(given_up.errors.max_error)
    again = fit(clip, clip.zero_base(), e, give_up=10.0 * whole.size)  # far above: coded whole, the same bytes
    assert again.sections == whole.sections


def test_fit_gives_up_in_a_later_round_whose_integers_grow_past_the_bytes() -> None:
    """CMU 02_05's sibling 05_02 (1,124 frames, eight rounds): bytes its first round's integers stay under but its
    final c.res section reaches are given up on before the rounds end (a base whose rounds go on growing, as the
    pattern model's on a 10-minute clip: 21 rounds to a file the correction alone beats)."""
    m = mocapz.load(data_path("cmu/bvh/05_02.bvh"))
    clip = Clip(m, True)
    e = resolve_target(m, {}).max_error
    coded: list[int] = []
    real = clip.quantise

    def counted(*args: Any, **kw: Any) -> Any:
        out = real(*args, **kw)
        coded.append(len(encode_int_matrix(out[0])))
        return out

    clip.quantise = counted  # type: ignore[method-assign]
    whole = fit(clip, clip.zero_base(), e)
    rounds = len(coded)
    give_up = 0.97 * len(whole.sections["c.res"])
    assert rounds >= 4 and coded[0] < give_up  # the first round alone does not reach the bytes
    coded.clear()
    given_up = fit(clip, clip.zero_base(), e, give_up=give_up)
    assert given_up.size == GAVE_UP and not given_up.sections
    assert 1 < len(coded) < rounds  # after a later round, before the last


@pytest.mark.slow
def test_a_model_that_cannot_win_is_given_up_and_the_file_is_the_same(monkeypatch: pytest.MonkeyPatch) -> None:
    """CMU backflip: the pattern codec's model is made (its own bytes under the correction alone's file) and then
    loses; its correction now stops after one round, and the file is byte for byte the one of every round."""
    m = mocapz.load(data_path("cmu/asfamc/backflip.amc"))
    real = search.fit
    sizes: list[int] = []

    def recorded(*args: Any, **kw: Any) -> Any:
        cor = real(*args, **kw)
        sizes.append(cor.size)
        return cor

    monkeypatch.setattr(search, "fit", recorded)
    quick = mocapz.compress(m, codec="patterns")
    assert GAVE_UP in sizes  # the model's correction was given up
    sizes.clear()

    def every_round(*args: Any, **kw: Any) -> Any:
        kw.pop("give_up", None)
        return recorded(*args, **kw)

    monkeypatch.setattr(search, "fit", every_round)
    slow = mocapz.compress(m, codec="patterns")
    assert GAVE_UP not in sizes and len(sizes) == 2  # both bases coded through every round
    assert quick == slow
