"""Random access in the lossy codecs' files: a long clip's correction streams are laid out in seekable chunks
(``c.head`` format 3, :mod:`mocapz.codecs.correction.window`), and ``decompress(frames=...)`` decodes only what
the frames need, giving the full decode's values to the bit."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.api import read_container
from mocapz.codecs.correction import lifting, window, wrap
from mocapz.errors import FormatError
from mocapz.format import entropy, seekable
from mocapz.format.container import Container
from mocapz.model.motion import MarkerMotion, Motion

CASES = {  # name: (shared file, frames kept, codec)
    "bvh": ("cmu/bvh/06_13.bvh", 1600, "quant"),
    "c3d_gaps": ("cmu/c3d/01_01.c3d", 1400, "quant"),
    "amc": ("cmu/asfamc/01_01.amc", 1300, "quant"),
    "bandai_30fps": ("other/bvh/bandai_namco/dataset-1_dance-short_normal_001.bvh", 1200, "patterns"),
}


def _clip(rel: str, frames: int) -> Motion | MarkerMotion:
    m = mocapz.load(data_path(rel))
    if isinstance(m, Motion):
        return m.slice(0, frames)
    return replace(m, positions=m.positions[:frames].copy(), metadata={})


@pytest.fixture(scope="module")
def coded() -> dict[str, tuple[bytes, Motion | MarkerMotion]]:
    out = {}
    for name, (rel, frames, codec) in CASES.items():
        data = mocapz.compress(_clip(rel, frames), codec=codec)
        out[name] = (data, mocapz.decompress(data))
    return out


def _starts(n: int) -> list[int]:
    """Window starts at the ends, on and beside the chunk and segment edges, and spread over the clip."""
    edges = [0, 1, 7, 8, 9, 127, 128, 129, 511, 512, 513, 1023, 1024, 1025, n - 40, n - 21, n - 20, n - 1]
    return sorted({a for a in edges + list(range(3, n, n // 23)) if 0 <= a < n})


@pytest.mark.parametrize("name", list(CASES))
def test_a_window_is_the_full_decode_to_the_bit(coded: dict, name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    data, full = coded[name]
    head = Container.from_bytes(data).sections["c.head"]
    assert head[0] == 3 and head[1] == 0  # the seekable layout on a zero base (the correction alone)

    def whole(*args: object, **kwargs: object) -> None:
        raise AssertionError("the whole clip was decoded for a window")

    monkeypatch.setattr(lifting, "decode_table", whole)  # a window must not take the full decode's path
    n = full.n_frames
    for a in _starts(n):
        for length in (1, 20, 300):
            b = min(n, a + length)
            part = mocapz.decompress(data, frames=slice(a, b))
            assert part.n_frames == b - a
            assert part.values.tobytes() == full.values[a:b].tobytes(), (a, b)  # every bit (-0.0, NaN)
            assert type(part) is type(full)


def test_a_window_decodes_a_small_share_of_the_values(coded: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    """20 frames of the middle of a clip: the range coder decodes a small share of the values a full decode
    does (counted, not timed)."""
    counted = []
    real = entropy._decode_values

    def counting(dec, scale, rows, cols, row0=0):  # noqa: ANN001, ANN202
        counted.append(rows * cols)
        return real(dec, scale, rows, cols, row0)

    monkeypatch.setattr(entropy, "_decode_values", counting)
    # the whole ASF/AMC clip (2,751 frames): its first 1,300 frames' coarse segments are most of what is range coded
    amc = mocapz.compress(mocapz.load(data_path(CASES["amc"][0])), codec="quant")
    for name, data in (("amc", amc), ("c3d_gaps", coded["c3d_gaps"][0])):
        counted.clear()
        n = mocapz.decompress(data).n_frames
        whole = sum(counted)
        counted.clear()
        mocapz.decompress(data, frames=slice(n // 2, n // 2 + 20))
        assert whole > 0 and sum(counted) < 0.2 * whole, (name, sum(counted), whole)


def test_the_seekable_layout_costs_little(monkeypatch: pytest.MonkeyPatch) -> None:
    """The same clip and target, the seekable layout against the single streams of shorter clips: within 2 % (on
    06_13 since the sparse planes' shallow zstd search, planes.SPARSE_SEARCH_LOG, 0.3 % smaller than them)."""
    m = _clip("cmu/bvh/06_13.bvh", 4906)
    seekable_size = len(mocapz.compress(m, codec="quant"))
    monkeypatch.setattr(window, "SEEK_MIN", 10**9)
    plain = mocapz.compress(m, codec="quant")
    assert Container.from_bytes(plain).sections["c.head"][0] == 2
    assert seekable_size < 1.02 * len(plain)


def test_clips_under_the_threshold_keep_the_single_streams() -> None:
    m = _clip("cmu/bvh/06_13.bvh", window.SEEK_MIN - 1)
    assert Container.from_bytes(mocapz.compress(m, codec="quant")).sections["c.head"][0] == 2


def test_running_values_and_segments_decode_any_rows() -> None:
    rng = np.random.default_rng(1)
    for rows, cols, chunk in [(615, 96, 64), (1, 3, 64), (64, 5, 64), (65, 5, 64), (129, 2, 1), (130, 2, 64),
                              (1000, 3, 7)]:
        v = np.cumsum(rng.laplace(0, 5, size=(rows, cols)).round().astype(np.int64), axis=0)
        v[rows // 2, 0] += 10**6  # beyond the range coder's model: escapes
        v[rows // 2 + 1:, -1] += 10**7
        data = seekable.pack_running(v, chunk)
        for a in range(0, rows, max(1, rows // 29)):
            for length in (1, 2, 5, chunk, chunk + 1, 200):
                b = min(rows, a + length)
                assert np.array_equal(seekable.read_running(data, v.shape, chunk, a, b), v[a:b]), (rows, chunk, a)
        sparse = np.where(rng.random((rows, cols)) < 0.05, rng.integers(-3, 4, (rows, cols)), 0)
        starts = list(range(0, rows, 100))
        for m in (sparse, np.diff(v, axis=0, prepend=0)):
            d = seekable.encode_segments(m, starts)
            got = seekable.decode_segments(d, m.shape, starts)
            assert np.array_equal(np.concatenate([got[i] for i in range(len(starts))]), m)
            last = seekable.decode_segments(d, m.shape, starts, [len(starts) - 1], rows)
            assert list(last) == [len(starts) - 1] and np.array_equal(last[len(starts) - 1], m[starts[-1]:])


def test_damaged_seekable_streams_fail_cleanly(coded: dict) -> None:
    """Bytes of the seekable streams flipped or cut: the correction's own decoders (not the API, which turns any
    exception into a FormatError) raise a FormatError or decode values, never another exception."""
    data, full = coded["amc"]
    box = Container.from_bytes(data)
    header = read_container(data)[1]
    rng = np.random.default_rng(7)
    n = full.n_frames
    outcomes = {"values": 0, "FormatError": 0}
    for section in ("c.res", "c.levels"):
        body = box.sections[section]
        for k in range(30):
            broken = bytearray(body)
            if k % 3 == 2:
                broken = broken[: int(rng.integers(1, len(body)))]
            else:
                broken[int(rng.integers(0, len(body)))] ^= 1 << int(rng.integers(0, 8))
            sections = {**box.sections, section: bytes(broken)}
            for decode in (lambda s=sections: wrap.apply_window(s, header, n // 2, n // 2 + 20),
                           lambda s=sections: wrap.apply(s, header, lambda *_: None)):
                try:
                    decode()
                    outcomes["values"] += 1
                except FormatError:
                    outcomes["FormatError"] += 1
    assert outcomes["FormatError"] > 0  # damage is seen, not only decoded into other values


def test_the_command_line_decodes_a_range_of_a_lossy_file(coded: dict, tmp_path) -> None:  # noqa: ANN001
    data, full = coded["bvh"]
    src = tmp_path / "clip.mcz"
    src.write_bytes(data)
    out = tmp_path / "part.bvh"
    run = subprocess.run([sys.executable, "-m", "mocapz", "decompress", str(src), "--frames", "700:730", "-o",
                          str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    part = mocapz.load(out)
    assert part.n_frames == 30
    assert np.allclose(part.values, full.values[700:730], atol=1e-4)  # as written to BVH text
