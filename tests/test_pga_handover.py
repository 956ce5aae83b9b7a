"""The pga encoder decodes its own seekable file twice, one after the other: for the ``turns`` it stores
(:func:`mocapz.codecs.pga.decode.with_turns`), then as the correction layer's base. The second decode takes the
Euler angles the first left (its IK not solved again) and must give exactly a fresh decode's values; a decode of
other sections, or an edited one, must not take them."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.codecs.pga import decode as pga_decode
from mocapz.codecs.pga.params import PGASettings
from mocapz.codecs.pga.ratecontrol import encode as pga_encode
from mocapz.model.motion import Motion


@pytest.fixture(scope="module")
def clip() -> Motion:
    m = mocapz.load(data_path("cmu/bvh/02_05.bvh"))
    assert isinstance(m, Motion)
    return m.slice(0, 1100)  # seekable (from 1,024 frames): the file has turns


def _streams_counted(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls: list[int] = []
    real = pga_decode.decode_streams

    def counted(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(pga_decode, "decode_streams", counted)
    return calls


def test_second_decode_takes_the_angles_and_matches_a_fresh_one(clip: Motion,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    sections = pga_encode(clip, geodesics=16)  # with_turns decoded them once, leaving their angles
    assert "turns" in sections
    s = PGASettings.from_bytes(sections["params"])
    calls = _streams_counted(monkeypatch)
    handed = pga_decode.decode_channels(clip.skeleton, s, sections, clip.n_frames)
    assert calls == []  # nothing decoded again
    fresh = pga_decode.decode_channels(clip.skeleton, s, sections, clip.n_frames)  # taken: decoded anew
    assert calls == [1]
    np.testing.assert_array_equal(handed, fresh)


def test_other_sections_or_an_edit_decode_anew(clip: Motion, monkeypatch: pytest.MonkeyPatch) -> None:
    sections = pga_encode(clip, geodesics=16)
    s = PGASettings.from_bytes(sections["params"])
    calls = _streams_counted(monkeypatch)
    kept = clip.n_frames - len(s.outliers)
    edited = pga_decode.decode_channels(clip.skeleton, s, sections, clip.n_frames, edit={0: np.zeros((kept, 3))})
    assert calls == [1] and edited.shape == (clip.n_frames, clip.skeleton.n_channels)  # an edit decodes anew
    pga_decode.decode_channels(clip.skeleton, s, sections, clip.n_frames)
    assert calls == [1, 1]  # and drops the angles left
    pga_encode(clip.slice(0, 1050), geodesics=16)  # leaves the 1,050 frames' angles
    calls.clear()
    pga_decode.decode_channels(clip.skeleton, s, sections, clip.n_frames)
    assert calls == [1]  # not the sections they are of
