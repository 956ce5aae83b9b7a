"""A rate search's shortcuts give the search's very bytes: PGA's memo of each stream by the settings it depends on
(a candidate codes and decodes only the streams its move changes), a short clip's candidates screened with the
compiled IK (the choice checked with the decoder), and the correction's bound search packing only the correction it
keeps (the others' sections are never asked for)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.codecs.correction.fit import Clip, fit
from mocapz.codecs.correction.search import bound_search
from mocapz.codecs.pga.encode import prepare
from mocapz.codecs.pga.params import PGASettings
from mocapz.codecs.pga.ratecontrol import _moves, evaluate_settings, search
from mocapz.codecs.target import Target


@pytest.mark.parametrize(("path", "frames"), [("cmu/bvh/09_06.bvh", 142), ("cmu/bvh/02_01.bvh", 200)])
def test_pga_memo_gives_every_candidates_sections_and_errors(path: str, frames: int) -> None:
    """Every move from two settings (every stream's setting changed once, and two in a row), evaluated with the
    memo warm from the others, against a Prepared of its own (an empty memo): the same sections, bytes and errors
    to the bit, on every frame and on a frame subset."""
    m = mocapz.load(data_path(path)).slice(0, frames)
    p = prepare(m)
    start = PGASettings(k=12, lod_root=0, lod_effectors=0, lod_coords=0, pos_step=0.05, coord_step=1e-3,
                        rot_step=2e-4, basis_bits=12, mean_step=5e-5)
    rows = np.arange(0, len(p.kept), 3)  # kept frames (an outlier frame is coded apart)
    settings = [start]
    for base in (start, start.replace(k=9, eff_mode=1, pos_step=0.2)):
        settings += [make() for _, make in _moves(base, {}, 1)]
    assert len({s.to_bytes() for s in settings}) == len(settings) > 20  # every move a new setting
    for s in settings + [settings[1]]:  # the last: a setting seen before, all from the memo
        for subset in (None, rows):
            fresh = prepare(m)
            got, want = evaluate_settings(p, s, subset), evaluate_settings(fresh, s, subset)
            assert got[0] == want[0] and got[1] == want[1], s
            assert got[2] == want[2], s
    assert p.memo  # what the candidates shared


def test_a_pga_search_lets_its_memo_go() -> None:
    m = mocapz.load(data_path("cmu/bvh/09_06.bvh")).slice(0, 60)
    p = prepare(m)
    sections, settings, log = search(p, {}, Target(max_distortion=1.0))
    assert len(log) > 2 and sections["data"] and not p.memo


def test_bound_search_packs_the_correction_it_keeps_as_a_fit_does(monkeypatch: pytest.MonkeyPatch) -> None:
    """A distortion target's bound search (several fits, packed lazily): the correction it returns has the sections
    of an eager fit at its bound, and those sections are packed only when asked for."""
    m = mocapz.load(data_path("cmu/bvh/05_02.bvh")).slice(0, 600)
    clip = Clip(m, True)
    fits: list = []
    import mocapz.codecs.correction.search as search_module

    real = search_module.fit

    def counted(*args: object, **kwargs: object):  # noqa: ANN202
        cor = real(*args, **kwargs)
        fits.append(cor)
        return cor

    monkeypatch.setattr(search_module, "fit", counted)
    cor = bound_search(clip, clip.zero_base(), Target(max_distortion=0.36), 16.0, clip.levels - 1)
    assert len(fits) >= 2 and all(callable(f.made) for f in fits if f is not cor)  # the others never packed
    eager = fit(clip, clip.zero_base(), cor.bound, 16.0, clip.levels - 1)
    assert not callable(eager.made)
    assert cor.sections == eager.sections and cor.size == eager.size and cor.errors == eager.errors
    assert not callable(cor.made)  # packed once asked, and kept


def test_a_short_clips_search_screened_with_the_compiled_ik_chooses_what_the_decoder_would(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A clip under ikjit.LAZY_FRAMES (its values the NumPy IK's): the candidates' errors estimated with the compiled
    IK, the choice checked with the decoder; the same settings and sections as a search decoding every candidate
    with the decoder, and the file meets the target when decoded."""
    from mocapz import aot
    from mocapz.codecs.pga import ikjit, ratecontrol

    if aot.kernels("ik") is None or not ikjit.enabled():
        pytest.skip("no kernels compiled ahead of time (make kernels), or turned off: the search does not screen")
    m = mocapz.load(data_path("cmu/bvh/09_06.bvh")).slice(0, 120)
    target = Target(max_distortion=0.5)
    p = prepare(m)
    assert ratecontrol.screens(p)
    screened = search(p, {}, target)
    assert any("checked on all frames" in x for x in screened[2])
    monkeypatch.setattr(ratecontrol, "screens", lambda p: False)
    plain = search(prepare(m), {}, target)
    assert screened[0] == plain[0] and screened[1] == plain[1]
    assert not any("checked on all frames" in x for x in plain[2])
    assert target.met(evaluate_settings(prepare(m), screened[1])[2])
