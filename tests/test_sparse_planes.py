"""The zstd search of a sparse matrix's byte planes (:data:`mocapz.format.planes.SPARSE_SEARCH_LOG`): the
correction's mostly-zero detail matrices of a real clip, packed with the shallow search, decode to the same
integers and come to no more bytes in all than with the level's own search."""

from __future__ import annotations

import numpy as np
import pytest

import mocapz
from mocapz.format import entropy, planes
from tests.conftest import data_path


@pytest.fixture(scope="module")
def sparse_matrices() -> list[np.ndarray]:
    """The sparse matrices of at least SPARSE_BYTES of planes zstd-packed by a quant encode of 06_13 (4,906
    frames: the seekable layout's detail levels)."""
    motion = mocapz.load(data_path("cmu/bvh/06_13.bvh"))
    seen: list[np.ndarray] = []
    pack = planes.pack_zigzag_columns

    def spy(v: np.ndarray, sparse: bool = False) -> bytes:
        if sparse:
            seen.append(np.array(v, copy=True))
        return pack(v, sparse)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(planes, "pack_zigzag_columns", spy)
        mp.setattr(entropy, "pack_zigzag_columns", spy)
        data = mocapz.compress(motion, "quant")
    back = mocapz.decompress(data)
    assert back.n_frames == motion.n_frames
    return [v for v in seen if v.size * _plane_bytes(v) >= planes.SPARSE_BYTES]


def _plane_bytes(v: np.ndarray) -> int:
    top = int(planes.zigzag(v).max()) if v.size else 0
    return max(1, (top.bit_length() + 7) // 8)


def test_sparse_search_round_trips_and_packs_no_larger(sparse_matrices: list[np.ndarray]) -> None:
    assert len(sparse_matrices) >= 2  # the one-stream and the finest level's at least
    shallow = deep = 0
    for v in sparse_matrices:
        assert np.count_nonzero(v) <= entropy.SPARSE * v.size
        fast, full = planes.pack_zigzag_columns(v, sparse=True), planes.pack_zigzag_columns(v)
        assert fast != full  # the shallow search is the one used
        rows, cols = v.shape
        assert np.array_equal(planes.unpack_zigzag_columns(fast, rows, cols), v)
        shallow, deep = shallow + len(fast), deep + len(full)
    assert shallow <= deep * 1.005


def test_small_or_dense_streams_keep_the_level_search() -> None:
    rng = np.random.default_rng(5)
    small = np.where(rng.random((300, 20)) < 0.03, rng.integers(-3, 4, (300, 20)), 0)  # 6 kB of planes
    assert planes.pack_zigzag_columns(small, sparse=True) == planes.pack_zigzag_columns(small)
