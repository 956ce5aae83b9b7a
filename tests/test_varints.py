"""The batched readers of the integer streams give what the one-at-a-time readers give: uvarints
(:func:`~mocapz.format.planes.read_uvarints`), running sums of byte-plane matrices
(:func:`~mocapz.format.planes.unpack_zigzag_running`) and the layout's number checks."""

from __future__ import annotations

import numpy as np
import pytest

from mocapz.errors import FormatError
from mocapz.format import layout_check
from mocapz.format.planes import (
    pack_zigzag_columns,
    read_uvarint,
    read_uvarints,
    unpack_zigzag_columns,
    unpack_zigzag_running,
    write_uvarint,
)


def _one_by_one(buf: bytes, pos: int, count: int) -> tuple[list[int], int]:
    out = []
    for _ in range(count):
        value, pos = read_uvarint(buf, pos)
        out.append(value)
    return out, pos


@pytest.mark.parametrize("seed", range(6))
def test_uvarints_read_at_once_equal_one_by_one(seed: int) -> None:
    rng = np.random.default_rng(seed)
    bits = rng.integers(0, 65, 300)
    values = [int(rng.integers(0, 1 << 62)) >> (64 - int(b)) if b < 64 else (1 << 64) - 1 - int(rng.integers(9))
              for b in bits]
    lead = bytes(rng.integers(0, 256, int(rng.integers(0, 5)), np.uint8))
    buf = lead + b"".join(write_uvarint(v) for v in values) + b"\x85\x01"
    got, pos = read_uvarints(buf, len(lead), len(values))
    assert got.dtype == np.uint64
    assert [int(v) for v in got] == values
    assert pos == _one_by_one(buf, len(lead), len(values))[1]
    assert read_uvarints(buf, len(lead), 0)[1] == len(lead)


@pytest.mark.parametrize("buf", [b"", b"\x80", b"\x05\x80\x80", b"\xff" * 11 + b"\x01", b"\xff" * 9 + b"\x02",
                                 b"\x01\x02" + b"\xff" * 12])
def test_damaged_uvarints_raise_what_one_by_one_raises(buf: bytes) -> None:
    for count in (1, 2, 3):
        try:
            expected = _one_by_one(buf, 0, count)
        except FormatError as exc:
            with pytest.raises(FormatError) as batch:
                read_uvarints(buf, 0, count)
            assert str(batch.value) == str(exc)
        else:
            got, pos = read_uvarints(buf, 0, count)
            assert ([int(v) for v in got], pos) == expected
    with pytest.raises(FormatError):
        read_uvarints(buf, 0, 3)


@pytest.mark.parametrize("width", [1, 2, 4, 8])
def test_running_sums_equal_cumsum(width: int) -> None:
    rng = np.random.default_rng(width)
    rows, cols = 257, 7
    top = {1: 60, 2: 10_000, 4: 1 << 28, 8: 1 << 40}[width]
    m = rng.integers(-top, top, (rows, cols))
    m[:, 2] = 0  # a still column
    if width == 8:  # the int64 extremes (sums of them would overflow: the first two rows only)
        m[0, 3], m[1, 3] = np.iinfo(np.int64).min, np.iinfo(np.int64).max
        m[2:, 3] = 0
    buf = pack_zigzag_columns(m)
    assert np.array_equal(unpack_zigzag_columns(buf, rows, cols), m)
    whole = np.cumsum(m, axis=0)
    for a, b in [(0, rows), (0, 1), (100, 120), (256, 257), (5, 5), (rows, rows)]:
        got = unpack_zigzag_running(buf, rows, cols, a, b)
        assert got.dtype == np.int64 and got.flags.c_contiguous
        assert np.array_equal(got, whole[a:b])


@pytest.mark.parametrize("values", [
    [0.0, 1, -2.5], [True, 1.0, 2.0], [1.0, float("inf"), 0.0], [float("nan"), 0, 0], [1 << 999, 0, 0],
    [1 << 1000, 0, 0], [-(1 << 2000), 0.0, 1.0], ["1", 0, 0], [None, 0, 0], [[1], 0, 0], [], [1e308, -1e308, 0],
])
def test_layout_numbers_checked_at_once_as_one_by_one(values: list) -> None:  # noqa: ANN001
    one = all(layout_check._is_real(v) for v in values)
    assert layout_check._reals(values) == one
