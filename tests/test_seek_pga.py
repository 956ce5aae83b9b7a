"""Random access in pga files: a clip coded with the seekable layout stores its angles' whole turns
(:mod:`mocapz.codecs.pga.turns`), so ``decompress(frames=...)`` solves the IK on those frames only and gives the
full decode's values to the bit."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz import _jit
from mocapz.codecs.pga import decode as pga_decode
from mocapz.codecs.pga import lifting, so3
from mocapz.codecs.pga.turns import SECTION, Turns
from mocapz.errors import FormatError
from mocapz.format.container import Container
from mocapz.model.motion import Motion

CASES = {  # name: (shared file, frames kept): a root turning past 180 degrees, an ASF/AMC skeleton, 30 fps
    "bvh_turning": ("cmu/bvh/06_13.bvh", 1500),
    "amc": ("cmu/asfamc/01_01.amc", 1100),
    "bandai_30fps": ("other/bvh/bandai_namco/dataset-1_dance-short_normal_001.bvh", 1100),
}


@pytest.fixture(scope="module")
def coded() -> dict[str, tuple[bytes, Motion]]:
    out = {}
    for name, (rel, frames) in CASES.items():
        m = mocapz.load(data_path(rel))
        assert isinstance(m, Motion) and m.n_frames >= frames
        data = mocapz.compress(m.slice(0, frames), codec="pga")
        full = mocapz.decompress(data)
        assert isinstance(full, Motion)
        out[name] = (data, full)
    return out


def _starts(n: int) -> list[int]:
    edges = [0, 1, 2, 127, 128, 511, 512, 1023, 1024, n - 21, n - 20, n - 1]
    return sorted({a for a in edges + list(range(5, n, n // 11)) if 0 <= a < n})


@pytest.mark.parametrize("name", list(CASES))
def test_a_window_is_the_full_decode_to_the_bit(coded: dict, name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    data, full = coded[name]
    sections = Container.from_bytes(data).sections
    assert SECTION in sections and sections["c.head"][:2] == bytes([3, 1])  # seekable, on the model's base

    def whole(*args: object, **kwargs: object) -> None:
        raise AssertionError("the IK was solved on every frame for a window")

    monkeypatch.setattr(pga_decode, "decode_kept", whole)
    n = full.n_frames
    for a in _starts(n):
        for length in (1, 20, 300):
            b = min(n, a + length)
            part = mocapz.decompress(data, frames=slice(a, b))
            assert isinstance(part, Motion) and part.n_frames == b - a
            assert np.array_equal(part.values, full.values[a:b]), (name, a, b)


def _continuous(values: np.ndarray, period: float) -> bool:
    """No step of half a turn or more between consecutive frames (as np.unwrap leaves angles)."""
    return bool((np.abs(np.diff(values, axis=0)) < period / 2).all())


def test_the_turns_keep_angles_running_on(coded: dict) -> None:
    """The stored centres give angles that run on over time as np.unwrap's do (the same angles modulo a turn,
    no step of half a turn where np.unwrap has none), and the turning clip needs some."""
    data, full = coded["bvh_turning"]
    box = Container.from_bytes(data)
    sk = full.skeleton
    events = Turns.from_bytes(box.sections[SECTION], full.n_frames, sk.rotation_columns())
    assert 0 < events.frames.size < 40
    legacy = {k: v for k, v in box.sections.items() if k != SECTION}
    old = mocapz.decompress(Container(box.codec, box.codec_version, box.layout, legacy).to_bytes())
    rot = sk.rotation_columns()
    turns = (full.values[:, rot] - old.values[:, rot]) / 360.0
    assert np.allclose(turns, np.round(turns), atol=1e-12)
    assert np.array_equal(full.values[:, ~rot], old.values[:, ~rot])
    for j in np.flatnonzero(rot):
        if _continuous(old.values[:, j], 360.0):
            assert _continuous(full.values[:, j], 360.0), j
    assert np.abs(full.values[:, rot]).max() > 200  # beyond half a turn


def test_turns_from_angles_and_bytes() -> None:
    rng = np.random.default_rng(5)
    frames, period = 700, 360.0
    cont = np.cumsum(rng.normal(0, 9, size=(frames, 6)), axis=0)  # continuous angles, several turns
    cont[:, 4] = 10.0  # a still column
    cont[:, 5] = 180.0 + rng.normal(0, 3, size=frames)  # hovering about half a turn
    raw = np.mod(cont + 180.0, period) - 180.0
    rotation = np.array([True, True, False, True, True, True, True, False])
    wide = np.zeros((frames, 8))
    wide[:, rotation] = raw
    events = Turns.of(wide, rotation, period)
    assert (events.columns == 6).sum() <= 1  # hovering: one move at most
    assert 5 not in events.columns.tolist()  # still
    back = Turns.from_bytes(events.to_bytes(), frames, rotation)
    whole = wide.copy()
    back.unwrapper()(whole, rotation, period)
    for got in (events, back):
        out = wide.copy()
        got.unwrapper()(out, rotation, period)
        assert np.array_equal(out, whole)
        d = out[:, rotation] - cont
        assert np.allclose(d - d[0], 0.0, atol=1e-9)  # the source's angles, up to whole turns of the first frame
        assert _continuous(out[:, rotation], period)
    for first in (0, 1, 333, 699):
        part = wide[first:first + 50].copy()
        back.unwrapper(first)(part, rotation, period)
        assert np.array_equal(part, whole[first:first + 50])
    empty = Turns.of(wide[:1] * 0, rotation, period)
    assert empty.frames.size == 0 and Turns.from_bytes(empty.to_bytes(), 1, rotation).frames.size == 0


def test_damaged_turns_are_format_errors() -> None:
    rotation = np.array([True, True, False])
    good = Turns(np.array([3, 3, 9]), np.array([0, 1, 0]), np.array([1, -2, 1])).to_bytes()
    back = Turns.from_bytes(good, 10, rotation)
    assert sorted(zip(back.frames.tolist(), back.columns.tolist(), back.turns.tolist(), strict=True)) == \
        [(3, 0, 1), (3, 1, -2), (9, 0, 1)]
    step = bytes([3 << 2])  # an event 3 frames on, one turn up
    assert Turns.from_bytes(bytes([1, 0, 1, 0]), 10, rotation).frames.tolist() == [0]  # a move on frame 0
    for bad, frames in [(good, 9),  # an event past the clip
                        (bytes([1, 2, 1]) + step, 10),  # column 2 is not a rotation
                        (bytes([2, 1, 1]) + step + bytes([0, 1]) + step, 10),  # columns out of order
                        (bytes([1, 0, 2, 3 << 2, 0]), 10),  # two moves on one frame
                        (bytes([1, 0, 1, 3 << 2 | 3]), 10),  # no such code
                        (bytes([1, 0, 1, 3 << 2 | 2, 2]), 10),  # "more than one turn", one turn
                        (good + b"\x00", 10), (good[:-1], 10), (b"\xff\xff\xff\x7f", 10)]:
        with pytest.raises(FormatError):
            Turns.from_bytes(bad, frames, rotation)


def test_without_the_compiled_kernels_a_window_is_cut_from_the_full_decode(coded: dict,
                                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """The NumPy path (no numba) sums a frame's values in an order that depends on the batch: a window is then
    cut from the full decode (the same values, whole-clip cost)."""
    data, _ = coded["amc"]
    old = _jit.set_enabled(False)
    try:
        full = mocapz.decompress(data)
        windowed = []
        real = pga_decode.decode_span
        monkeypatch.setattr(pga_decode, "decode_span", lambda *a, **k: windowed.append(1) or real(*a, **k))
        for a, b in [(0, 20), (600, 620), (1080, 1100)]:
            assert np.array_equal(mocapz.decompress(data, frames=slice(a, b)).values, full.values[a:b])
        assert not windowed
    finally:
        _jit.set_enabled(old)


def test_short_clips_keep_np_unwrap() -> None:
    """Clips under the seekable length store no turns (their bytes as before) and decode whole."""
    m = mocapz.load(data_path("cmu/bvh/06_13.bvh")).slice(0, 600)
    data = mocapz.compress(m, codec="pga")
    assert SECTION not in Container.from_bytes(data).sections
    full = mocapz.decompress(data)
    assert np.array_equal(mocapz.decompress(data, frames=slice(100, 120)).values, full.values[100:120])


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 33, 257, 1030])
def test_trajectory_windows_are_the_whole_decode_to_the_bit(n: int) -> None:
    """Rows of the multiscale trajectories (positions and rotations), decoded alone, for every level of detail
    dropped or kept."""
    rng = np.random.default_rng(n)
    x = np.cumsum(rng.normal(0, 1, size=(n, 4)), axis=0)
    r = so3.exp(np.cumsum(rng.normal(0, 0.05, size=(n, 3)), axis=0))
    for lod in (0, 1, 2):
        q, _ = lifting.encode_rn(x, 0.01, lod)
        qr, _ = lifting.encode_so3(r, 0.002, lod)
        whole, whole_r = lifting.decode_rn(q, n, 0.01, lod), lifting.decode_so3(qr, n, 0.002, lod)
        for a in sorted({0, n // 2, n - 1}):
            for length in (1, 7, 100):
                b = min(n, a + length)
                assert np.array_equal(lifting.decode_rn_window(q, n, 0.01, lod, a, b), whole[a:b])
                assert np.array_equal(lifting.decode_so3_window(qr, n, 0.002, lod, a, b), whole_r[a:b])
