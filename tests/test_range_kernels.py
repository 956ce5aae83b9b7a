"""The compiled range decoder (:mod:`mocapz.format.rangekernels`) gives constriction's symbols: on every coder
of :mod:`mocapz.format.entropy`, on seekable segments decoded in part, on real files of every lossy codec, and it
turns corrupt data into a FormatError or values, never a crash."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz import _jit
from mocapz.errors import FormatError
from mocapz.format import entropy, seekable

pytest.importorskip("numba")
pytest.importorskip("constriction")


@pytest.fixture
def reference(monkeypatch: pytest.MonkeyPatch):  # noqa: ANN201
    """A context switch: inside ``with reference():`` the range decoder is constriction's."""
    from contextlib import contextmanager

    assert entropy._range_kernels(entropy.LAZY_VALUES) is not None  # loaded: the compiled path is the default

    @contextmanager
    def constriction_only():  # noqa: ANN202
        with monkeypatch.context() as m:
            m.setattr(entropy, "_range_kernels", lambda values: None)
            yield

    return constriction_only


def _matrices() -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    out = []
    for rows, cols, scale in ((1, 1, 1.0), (3, 5, 0.2), (300, 7, 3.0), (600, 40, 40.0), (1000, 3, 2000.0)):
        v = np.round(rng.laplace(0, scale, (rows, cols))).astype(np.int64)
        out.append(v)
    sparse = np.zeros((700, 30), dtype=np.int64)
    sparse[rng.integers(0, 700, 90), rng.integers(0, 30, 90)] = rng.integers(-5, 6, 90)
    sparse[5, 3] = 10**9  # an escape
    out.append(sparse)
    wide = np.round(rng.laplace(0, 1, (260, 9))).astype(np.int64)
    wide[:, 4] *= 100000  # escapes in one column
    out.append(wide)
    tails = np.zeros((600, 8), dtype=np.int64)  # zeros and far outliers: a tiny scale, symbols on the leaky floor
    at = rng.integers(0, tails.size, 120)
    tails.flat[at] = rng.integers(50, 30000, 120) * rng.choice([-1, 1], 120)
    out.append(tails)
    return out


@pytest.mark.parametrize("coder", [entropy.CODER_RANGE, entropy.CODER_RANGE_DELTA])
def test_compiled_decoder_equals_constriction(coder: int, reference) -> None:  # noqa: ANN001
    for v in _matrices():
        data = entropy.encode_int_matrix(v, coder)
        fast = entropy.decode_int_matrix(data)
        with reference():
            slow = entropy.decode_int_matrix(data)
        assert np.array_equal(fast, v) and np.array_equal(slow, v)


def test_segments_decoded_in_part_equal_constriction(reference) -> None:  # noqa: ANN001
    rng = np.random.default_rng(3)
    v = np.round(rng.laplace(0, 4.0, (3000, 12))).astype(np.int64)
    starts = [0, 700, 1500, 2900]
    data = seekable.encode_segments(v, starts)
    for wanted, until in (([1], None), ([0, 2], 1600), ([3], None), ([2], 1501)):
        fast = seekable.decode_segments(data, v.shape, starts, wanted, until)
        with reference():
            slow = seekable.decode_segments(data, v.shape, starts, wanted, until)
        assert fast.keys() == slow.keys() == set(wanted)
        for i in wanted:
            assert np.array_equal(fast[i], slow[i])
            assert np.array_equal(fast[i], v[starts[i]:starts[i] + len(fast[i])])


@pytest.mark.parametrize("codec", ["quant", "pga", "patterns"])
def test_real_files_decode_to_the_bit(codec: str, reference) -> None:  # noqa: ANN001
    m = mocapz.load(data_path("cmu/bvh/02_05.bvh")).slice(0, 1300)
    data = mocapz.compress(m, codec=codec, max_error="1cm")
    fast, part = mocapz.decompress(data), mocapz.decompress(data, frames=slice(600, 620))
    with reference():
        slow = mocapz.decompress(data)
    assert np.array_equal(fast.values, slow.values)
    assert np.array_equal(part.values, slow.values[600:620])


def test_corrupt_streams_give_format_errors_or_values(reference) -> None:  # noqa: ANN001
    rng = np.random.default_rng(11)
    v = np.round(rng.laplace(0, 3.0, (400, 6))).astype(np.int64)
    data = bytearray(entropy.encode_int_matrix(v, entropy.CODER_RANGE_DELTA))
    assert entropy.decode_int_matrix(bytes(data)).shape == v.shape
    errors = 0
    for trial in range(200):
        bad = bytearray(data)
        pos = rng.integers(len(bad) // 3, len(bad))
        bad[pos] ^= 1 << int(rng.integers(0, 8))
        try:
            out = entropy.decode_int_matrix(bytes(bad))
        except FormatError:
            errors += 1
            continue
        assert out.shape == v.shape, trial
    assert errors > 0  # the kernel's own check of the point (a flip in the body puts it out of range at times)


def test_the_switch_turns_the_kernel_off() -> None:
    old = _jit.set_enabled(False)
    try:
        assert entropy._range_kernels(entropy.LAZY_VALUES) is None
        assert type(entropy.range_decoder(b"\0" * 8, 10**7)) is entropy.RangeReader
    finally:
        _jit.set_enabled(old)
    assert type(entropy.range_decoder(b"\0" * 8, 10**7)) is entropy.CompiledRangeReader
