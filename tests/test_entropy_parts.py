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
    _fuzz(data, rows, GROUPS, 200, 0)


def _fuzz(data: bytes, rows: list[int], groups: np.ndarray, n: int, seed: int) -> None:
    """Any damage (a random byte flipped, ``n`` times): a FormatError or parts of the shapes asked for, never
    anything else."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        d = bytearray(data)
        d[int(rng.integers(0, len(d)))] ^= int(rng.integers(1, 256))
        try:
            back = entropy_parts.decode(bytes(d), rows, groups.size, groups)
        except FormatError:
            continue
        assert [b.shape for b in back] == [(r, groups.size) for r in rows]


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


def _with_zero_groups(rows: list[int], seed: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Parts of 8 six-channel joints: the position channels all zero (a BVH joint's constant offsets), some joints
    all zero in some parts (still in a block), an escape."""
    rng = np.random.default_rng(seed)
    groups = np.repeat(np.arange(8), 6)
    parts = []
    for r in rows:
        p = np.round(rng.laplace(0, 2.0 ** rng.uniform(-3, 5, 8)[groups], (r, 48))).astype(np.int64)
        p[:, (np.arange(48) % 6) < 3] = 0
        p[:, (rng.random(8) < 0.4)[groups]] = 0
        parts.append(p)
    if rows[-1]:
        parts[-1][0, 5] = -(10**9)
    return parts, groups


@pytest.mark.parametrize(("rows", "seed"), [([4, 4, 8, 16], 0), ([1, 8, 0, 16, 32], 1), ([0, 3], 2), ([40, 300], 3)])
def test_zero_groups_are_masked_and_cost_less(rows: list[int], seed: int) -> None:
    parts, groups = _with_zero_groups(rows, seed)
    plain = min(entropy_parts._encode(parts, groups, 0), entropy_parts._encode(parts, np.arange(48),
                                                                              entropy_parts.PER_COLUMN), key=len)
    data = entropy_parts.encode(parts, groups)
    assert data[0] & entropy_parts.ZEROS and len(data) < len(plain)
    for flag, g in ((entropy_parts.ZEROS, groups), (entropy_parts.ZEROS | entropy_parts.PER_COLUMN, np.arange(48))):
        back = entropy_parts.decode(entropy_parts._encode(parts, g, flag), rows, 48, groups)
        for a, b in zip(parts, back, strict=True):
            np.testing.assert_array_equal(a, b)


def test_masked_streams_read_the_same_with_the_compiled_decoder(monkeypatch: pytest.MonkeyPatch) -> None:
    kernels = pytest.importorskip("mocapz.format.rangekernels")
    from mocapz.format import entropy

    monkeypatch.setattr(entropy, "range_decoder", lambda body, values=0: entropy.CompiledRangeReader(
        np.frombuffer(body, dtype=np.uint32).copy(), kernels))
    for seed in range(6):
        rows = [4, 8, 0, 16, 32]
        parts, groups = _with_zero_groups(rows, seed)
        back = entropy_parts.decode(entropy_parts._encode(parts, groups, entropy_parts.ZEROS), rows, 48, groups)
        for a, b in zip(parts, back, strict=True):
            np.testing.assert_array_equal(a, b)


def test_damaged_masked_streams_are_format_errors() -> None:
    rows = [4, 8, 16, 32]
    parts, groups = _with_zero_groups(rows, 4)
    data = entropy_parts._encode(parts, groups, entropy_parts.ZEROS)
    for bad in (data[:2], data[:-1], data + b"\0", data[:1] + bytes([0x0F]) + data[2:], data[:2] + b"\x10" + data[3:]):
        with pytest.raises(FormatError):
            entropy_parts.decode(bad, rows, 48, groups)
    _fuzz(data, rows, groups, 300, 1)


def test_a_30fps_streams_blocks_mask_their_still_channels(monkeypatch: pytest.MonkeyPatch) -> None:
    """A slow 30-fps walk streamed at 1 cm (32-frame blocks of 44 six-channel joints: half the columns zero in a
    block's parts): the masks take 7 % off the stream (measured 15,278 -> 14,148 B), every target as before."""
    path = DATA / "other/bvh/bandai_namco/dataset-2_walk_elderly_004.bvh"
    if not path.exists():
        pytest.skip(f"{path} not found")
    m = mocapz.load(path)
    masked = _stream(m)
    flags = [b["c.res"][1] for b in mocapz.format.stream.read_stream(masked).blocks if b["c.res"][0] & lifting.JOINT]
    assert sum(bool(f & entropy_parts.ZEROS) for f in flags) >= len(flags) // 2 > 0, flags
    rep = mocapz.evaluate(m, mocapz.decompress(masked))
    assert rep.max_err_cm <= 1.0 + 1e-9 and rep.jitter_pct <= 4.5
    monkeypatch.setattr(entropy_parts, "_encode_masked", lambda *a: b"\xff" * 10**6)  # never the smaller
    assert len(masked) <= 0.95 * len(_stream(m))
