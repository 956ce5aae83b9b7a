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


@pytest.mark.parametrize("search_bits", [1, 5000, entropy_costs.SEARCH_BITS])
def test_blocks_costed_together_pick_each_blocks_codes(search_bits: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """:func:`entropy_costs.scale_codes` costs whole blocks of small values together (their histograms padded to
    the largest value of the batch) and the candidates of a block of larger values together: the codes of each
    block costed alone, whatever the batch (``SEARCH_BITS``), on synthetic matrices (blocks of large values among
    small ones, a partial last block) and a real clip's correction integers."""
    rng = np.random.default_rng(8)
    mixed = np.round(rng.laplace(0, 1.5, (1300, 17))).astype(np.int64)
    mixed[600:620, 3] = 700  # one whole block with values beyond the table, and the partial last one
    mixed[-5:, :2] = -90
    m = mocapz.load(data_path("cmu/bvh/02_05.bvh")).slice(0, 700)
    real = entropy.decode_int_matrix(entropy.encode_int_matrix(np.diff(np.round(m.channels * 100), axis=0)
                                                               .astype(np.int64)))
    monkeypatch.setattr(entropy_costs, "SEARCH_BITS", search_bits)
    for v in [*_matrices(), mixed, real]:
        for steps, bias, offsets, top in ((4, entropy.QUARTER_BIAS, range(-4, 13), entropy.QUARTER_TOP),
                                          (8, 64, range(-8, 25, 2), 255)):
            got = entropy_costs.scale_codes(v, entropy.BLOCK, steps, bias, offsets, top)
            off = np.asarray(offsets, dtype=np.float64)
            alone = [entropy_costs._block_codes(v[b:b + entropy.BLOCK], v.shape[1], steps, bias, off, top)
                     for b in range(0, max(len(v), 1), entropy.BLOCK)]
            assert np.array_equal(got, np.array(alone).reshape(got.shape)), (v.shape, steps)


def test_compiled_scale_search_picks_numpys_codes(monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled scale search of whole blocks (:func:`mocapz.format.rangekernels.histogram_codes`) picks the codes
    of NumPy's histogram costs: on synthetic matrices (dense, sparse, half zeros, values past the table) and on every
    matrix the encoders search while coding real clips (quant, patterns and pga; skeleton and markers), at both
    scale precisions; and the files are the same bytes either way."""
    pytest.importorskip("numba")
    from mocapz.format import rangekernels

    rng = np.random.default_rng(3)
    mats = _matrices()
    for i in range(120):
        rows, cols = int(rng.integers(1, 2000)), int(rng.integers(1, 60))
        spread = float(rng.choice([0.1, 1.0, 8.0, 40.0, 300.0]))
        v = np.round(rng.laplace(0, spread, (rows, cols))).astype(np.int64)
        mats.append(np.where(rng.random((rows, cols)) < (0.9 if i % 3 == 0 else 0.0), 0, v))
    seen: list[np.ndarray] = []
    real = entropy_costs.scale_codes

    def keep(values, *args, **kw):  # noqa: ANN001, ANN002, ANN003, ANN202
        seen.append(np.array(values))
        return real(values, *args, **kw)

    monkeypatch.setattr(entropy_costs, "scale_codes", keep)
    monkeypatch.setattr(entropy, "scale_codes", keep)
    clips = [(data_path("cmu/bvh/02_05.bvh"), 1200), (data_path("cmu/c3d/01_01.c3d"), 600)]
    for path, frames in clips:
        m = mocapz.load(path)
        m = m.slice(0, frames)
        for codec in ("quant", "patterns", "pga") if hasattr(m, "skeleton") else ("quant", "patterns"):
            with_kernel = mocapz.compress(m, codec)
            with monkeypatch.context() as mp:
                mp.setattr(entropy, "_range_kernels", lambda values: None)
                assert mocapz.compress(m, codec) == with_kernel, (path, codec)
    assert len(seen) > 20
    for v in mats + seen:
        for steps, bias, offsets, top in ((4, entropy.QUARTER_BIAS, range(-4, 13), entropy.QUARTER_TOP),
                                          (entropy.SCALE_STEPS, 64, range(-8, 25, 2), 255)):
            numpy_codes = real(v, entropy.BLOCK, steps, bias, offsets, top)
            compiled = real(v, entropy.BLOCK, steps, bias, offsets, top, kernels=rangekernels)
            assert np.array_equal(numpy_codes, compiled), (v.shape, steps)
