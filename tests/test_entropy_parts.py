"""The parts of one lifting in a single range stream (:mod:`mocapz.format.entropy_parts`, layout
``lifting.JOINT``): exact round trips, a scale per column where a group's columns differ, damaged streams, and
the bytes it saves on a real stream's blocks and short clips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import mocapz
from mocapz.codecs.correction import lifting
from mocapz.errors import FormatError
from mocapz.format import entropy_parts
from mocapz.format.entropy import LIMIT

pytest.importorskip("constriction")

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
GROUPS = np.repeat(np.arange(10), 3)


def _parts(rows: list[int], seed: int, groups: np.ndarray = GROUPS) -> list[np.ndarray]:
    """Laplace integers, a scale per group (1/8 to 64), finer parts smaller (a lifting's levels)."""
    rng = np.random.default_rng(seed)
    scale = 2.0 ** rng.uniform(-3, 6, groups.max() + 1)[groups]
    return [np.round(rng.laplace(0, scale / (1 + i), (r, groups.size))).astype(np.int64) for i, r in enumerate(rows)]


@pytest.mark.parametrize(("rows", "seed"), [([1], 0), ([4, 4, 8, 16, 32, 64], 1), ([1, 8, 8, 16], 2),
                                            ([0, 2, 4], 3), ([300, 512], 4), ([3, 0, 0, 5], 5)])
def test_round_trip(rows: list[int], seed: int) -> None:
    parts = _parts(rows, seed)
    data = entropy_parts.encode(parts, GROUPS)
    back = entropy_parts.decode(data, rows, GROUPS.size, GROUPS)
    assert [b.shape for b in back] == [(r, GROUPS.size) for r in rows]
    for a, b in zip(parts, back, strict=True):
        np.testing.assert_array_equal(a, b)


def test_escapes_and_a_scale_per_column_where_a_group_mixes_columns() -> None:
    parts = _parts([4, 8, 16], 7)
    parts[1][2, 5], parts[2][9, 0], parts[0][0, 29] = 10**12, -(10**9), LIMIT
    data = entropy_parts.encode(parts, GROUPS)
    for a, b in zip(parts, entropy_parts.decode(data, [4, 8, 16], 30, GROUPS), strict=True):
        np.testing.assert_array_equal(a, b)
    # a joint's three position channels all zero beside its three rotations (6-channel joints): shared scales
    # would code the zeros under the rotations' scale, so every column gets its own
    mixed = np.repeat(np.arange(5), 6)
    parts = _parts([8, 8, 16], 8, mixed)
    for p in parts:
        p[:, (np.arange(30) % 6) < 3] = 0
    data = entropy_parts.encode(parts, mixed)
    assert data[0] & entropy_parts.PER_COLUMN
    assert len(data) < len(entropy_parts._encode(parts, mixed, 0))
    for a, b in zip(parts, entropy_parts.decode(data, [8, 8, 16], 30, mixed), strict=True):
        np.testing.assert_array_equal(a, b)


def test_damaged_streams_are_format_errors() -> None:
    rows = [4, 8, 16, 32]
    parts = _parts(rows, 9)
    data = entropy_parts.encode(parts, GROUPS)
    for bad in (b"", data[:-1], data + b"\0", bytes([0x0F]) + data[1:], bytes([0x20 | data[0]]) + data[1:]):
        with pytest.raises(FormatError):
            entropy_parts.decode(bad, rows, 30, GROUPS)
    with pytest.raises(FormatError):
        entropy_parts.decode(data, rows, 30, GROUPS[:-1])  # not the writer's groups
    rng = np.random.default_rng(0)
    for _ in range(200):  # any damage: a FormatError or parts of the shapes asked for, never anything else
        d = bytearray(data)
        d[int(rng.integers(0, len(d)))] ^= int(rng.integers(1, 256))
        try:
            back = entropy_parts.decode(bytes(d), rows, 30, GROUPS)
        except FormatError:
            continue
        assert [b.shape for b in back] == [(r, 30) for r in rows]


def test_lifting_reads_the_joint_layout_only_with_the_groups() -> None:
    rng = np.random.default_rng(1)
    q = np.round(rng.laplace(0, 2.0, (129, 30))).astype(np.int64)
    data = lifting.pack(q, 129, 5, None, GROUPS)
    assert data[0] & lifting.JOINT
    np.testing.assert_array_equal(lifting.read(data, 129, 30, 5, None, GROUPS), q)
    with pytest.raises(FormatError, match="layout"):
        lifting.read(data, 129, 30, 5)


def _stream(m: mocapz.Motion) -> bytes:
    enc = mocapz.StreamEncoder(m, codec="quant", max_error="1cm")
    return enc.write(m.values) + enc.close()


def test_a_real_streams_blocks_take_it_and_cost_less(monkeypatch: pytest.MonkeyPatch) -> None:
    """02_05's first 640 frames streamed at 1 cm (blocks of 128 frames, six lifting parts each): one range
    stream a block instead of one a part: -5.5 % of the whole stream (measured: 4,137 -> 3,909 B; every block
    takes it; -8.5 %, 4,272 -> 3,910 B, before a block's feet were held on the stream's sums so far, which
    changed the levels the parts' layout is chosen on)."""
    path = DATA / "cmu/bvh/02_05.bvh"
    if not path.exists():
        pytest.skip(f"{path} not found")
    m = mocapz.load(path).slice(0, 640)
    joint = _stream(m)
    layouts = [b["c.res"][0] for b in mocapz.format.stream.read_stream(joint).blocks]
    assert sum(bool(x & lifting.JOINT) for x in layouts) >= 4, layouts
    back = mocapz.decompress(joint)
    assert mocapz.evaluate(m, back).max_err_cm <= 1.0 + 1e-9
    monkeypatch.setattr(lifting, "HAVE_CONSTRICTION", False)  # the layouts before it
    apart = _stream(m)
    assert len(joint) <= 0.96 * len(apart), (len(joint), len(apart))
