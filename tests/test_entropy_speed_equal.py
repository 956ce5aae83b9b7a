"""The scale search on a block's histogram (:func:`mocapz.format.entropy_costs._histogram`) picks the scale codes the
row-by-row search picks, on synthetic matrices and on the correction streams of real clips."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.format import entropy, entropy_costs


def _matrices() -> list[np.ndarray]:
    rng = np.random.default_rng(5)
    out = [np.round(rng.laplace(0, s, (r, c))).astype(np.int64)
           for r, c, s in ((1, 1, 1.0), (300, 7, 0.2), (700, 30, 2.0), (513, 12, 9.0), (257, 5, 60.0))]
    sparse = np.zeros((2000, 40), dtype=np.int64)
    sparse[rng.integers(0, 2000, 300), rng.integers(0, 40, 300)] = rng.integers(-3, 4, 300)
    out.append(sparse)
    out.append(np.zeros((256, 3), dtype=np.int64))
    return out


def _both(v: np.ndarray, monkeypatch: pytest.MonkeyPatch) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    fast = entropy._quarter_scales(v), entropy._block_scales(v)
    with monkeypatch.context() as m:
        m.setattr(entropy_costs, "HIST_VALUES", 0)  # every block row by row
        slow = entropy._quarter_scales(v), entropy._block_scales(v)
    return (*fast, *slow)


def test_histogram_scales_equal_row_by_row(monkeypatch: pytest.MonkeyPatch) -> None:
    for v in _matrices():
        q4, q8, s4, s8 = _both(v, monkeypatch)
        assert np.array_equal(q4, s4) and np.array_equal(q8, s8), v.shape


def test_real_files_code_the_same_bytes(monkeypatch: pytest.MonkeyPatch) -> None:
    m = mocapz.load(data_path("cmu/bvh/02_05.bvh")).slice(0, 900)
    fast = mocapz.compress(m, codec="quant", max_error="1cm")
    monkeypatch.setattr(entropy_costs, "HIST_VALUES", 0)
    assert mocapz.compress(m, codec="quant", max_error="1cm") == fast


def test_table_bits_equal_computed_bits() -> None:
    """The scale search's bits from the table of every value under every code (:func:`entropy.code_bits`) are the
    very numbers computed for each block, on histograms and on blocks of values beyond the table."""
    rng = np.random.default_rng(11)
    for trial in range(60):
        rows, cols = int(rng.integers(1, 257)), int(rng.integers(1, 40))
        blk = np.abs(np.round(rng.laplace(0, rng.uniform(0.1, 200.0), (rows, cols))))
        if trial % 2:
            blk = np.minimum(blk, entropy.HIST_VALUES - 1)
        for steps, bias, top in ((4, entropy.QUARTER_BIAS, entropy.QUARTER_TOP), (8, 64, 255), (2, 16, 127)):
            codes = np.clip(rng.integers(0, top, cols)[None, :] + np.arange(-4, 13)[:, None], 0, top).astype(float)
            hist = entropy._histogram(blk)
            computed = entropy._candidate_bits(hist, 2.0 ** ((codes - float(bias)) / steps))
            assert np.array_equal(entropy.code_bits(hist, codes, steps, bias), computed), (trial, steps)
