"""The compiled range encoder (:func:`mocapz.format.rangekernels.encode_laplace`, :mod:`mocapz.format.rangewriter`)
writes constriction's words: on random streams of every kind (a renormalisation leaving the interval across a word
boundary, its word held back for a carry, is common: about one in six; a second one before that resolves needs an
interval under 2**32 across the boundary, about 2**-32 of them, and no random stream reaches it), coded in one call
or several, and on real files of every lossy codec (the same bytes with either writer)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.format import entropy, rangewriter

pytest.importorskip("numba")
pytest.importorskip("constriction")


@pytest.fixture(scope="module")
def kernels():  # noqa: ANN201
    k = entropy._range_kernels(entropy.LAZY_VALUES)
    assert k is not None
    return k


def _stream(rng: np.random.Generator, trial: int) -> tuple[np.ndarray, np.ndarray, int]:
    rows, cols = int(rng.integers(0, 300)), int(rng.integers(1, 10))
    scale = 10 ** rng.uniform(-1.5, 4, size=(rows // 64 + 2, cols))
    v = np.round(rng.laplace(0, 1, (rows, cols)) * scale[np.arange(rows) // 64]).astype(np.int64)
    if trial % 4 == 0:
        v[rng.random(v.shape) < 0.85] = 0
    if trial % 5 == 0 and v.size:
        v.flat[rng.integers(0, v.size)] = -(10**12)  # an escape: clipped to the limit
    return v, scale, int(rng.integers(0, 64))


def test_compiled_writer_writes_constrictions_words(kernels) -> None:  # noqa: ANN001
    rng = np.random.default_rng(11)
    words = 0
    for trial in range(600):
        v, scale, row0 = _stream(rng, trial)
        cut = int(rng.integers(0, v.shape[0] + 1))
        bodies = []
        for w in (rangewriter.RangeWriter(), rangewriter.CompiledRangeWriter(kernels)):
            entropy.encode_differences(w, np.arange(trial % 7) - 3, trial % len(entropy.DELTA_SCALES))
            w.laplace(v[:cut], scale, row0, 64, entropy.LIMIT)  # two calls: one stream
            w.laplace(v[cut:], scale, row0 + cut, 64, entropy.LIMIT)
            bodies.append(w.body())
        assert bodies[0] == bodies[1], trial
        words += len(bodies[0]) // 4
    assert words > 100_000


def test_an_empty_stream_has_no_words(kernels) -> None:  # noqa: ANN001
    w = rangewriter.CompiledRangeWriter(kernels)
    w.laplace(np.zeros((0, 3), dtype=np.int64), np.ones((1, 3)), 0, 64, entropy.LIMIT)
    assert w.body() == rangewriter.RangeWriter().body() == b""


@pytest.mark.parametrize("codec", ["quant", "patterns", "pga"])
def test_files_are_the_same_with_either_writer(codec: str, monkeypatch: pytest.MonkeyPatch) -> None:
    m = mocapz.load(data_path("cmu/bvh/02_05.bvh")).slice(0, 1200)
    compiled = mocapz.compress(m, codec)
    monkeypatch.setattr(entropy, "range_writer", lambda values=0: rangewriter.RangeWriter())
    assert mocapz.compress(m, codec) == compiled
