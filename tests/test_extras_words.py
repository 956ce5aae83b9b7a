"""The C3D word matrices' candidate codings (:func:`mocapz.format.extras_words.encode_words`): the raw words row by
row through xz are tried on small matrices only (a second of analog samples, where they can be the smallest), not
on a whole clip's (the slowest candidate, never the smallest on a shared C3D); every coding decodes to the words."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.format import extras_words as W


def _analogs(rel: str) -> tuple[np.ndarray, bool, int]:
    extras = mocapz.load(data_path(rel)).metadata["c3d"]
    return extras.analog_words, extras.is_float, extras.processor


def _tried(monkeypatch: pytest.MonkeyPatch, words: np.ndarray, is_float: bool, processor: int) -> tuple[bytes, list]:
    """The coding of ``words`` and the inputs xz was given."""
    seen: list[bytes] = []
    real = W.xz

    def recording(data: bytes, extreme: bool = False) -> bytes:
        seen.append(data)
        return real(data, extreme)

    monkeypatch.setattr(W, "xz", recording)
    out = W.encode_words(words, is_float, processor)
    monkeypatch.undo()
    return out, seen


def test_a_whole_clips_analogs_are_not_tried_row_by_row(monkeypatch: pytest.MonkeyPatch) -> None:
    words, is_float, processor = _analogs("other/markers/pyomeca/markers_analogs.c3d")
    assert words.nbytes // 2 > W.ROW_MAJOR_BYTES  # stored as 32-bit words: well past the bound
    out, seen = _tried(monkeypatch, words, is_float, processor)
    assert words.astype("<u4").tobytes() not in seen
    assert np.ascontiguousarray(words.T).astype("<u4").tobytes() in seen
    assert np.array_equal(W.decode_words(out, words.shape, is_float, processor), words)


def test_a_second_of_analogs_is_tried_row_by_row(monkeypatch: pytest.MonkeyPatch) -> None:
    """Eb015pi's analogs: 16 channels at 4 samples a frame; one of its 1-s blocks packs smallest row by row."""
    words, is_float, processor = _analogs("other/markers/btkdata/c3d_samples/Eb015pi.c3d")
    modes = []
    for a in range(0, words.shape[0] - 512 + 1, 512):
        block = words[a:a + 512]
        out, seen = _tried(monkeypatch, block, is_float, processor)
        assert block.astype("<i2").tobytes() in seen
        assert np.array_equal(W.decode_words(out, block.shape, is_float, processor), block)
        modes.append(out[0])
    assert W.MODE_XZ in modes
