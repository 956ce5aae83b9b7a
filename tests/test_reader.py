"""``mocapz.open`` / :class:`mocapz.Reader`: a file read and checked once, then frame ranges decoded on demand, each
the very values ``decompress(data, frames=...)`` (and a full decode) give, for every kind of file."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.errors import FormatError, OptionError
from mocapz.model.motion import MarkerMotion, Motion


def _values(m: Motion | MarkerMotion) -> np.ndarray:
    return m.values if isinstance(m, Motion) else m.positions


def _same(a: Motion | MarkerMotion, b: Motion | MarkerMotion) -> bool:
    """Equal to the bit (NaN where NaN), C3D extras included."""
    va, vb = _values(a), _values(b)
    if va.shape != vb.shape or not np.array_equal(va, vb, equal_nan=True):
        return False
    ea, eb = a.metadata.get("c3d"), b.metadata.get("c3d")
    return (ea is None) == (eb is None) and (ea is None or repr(ea) == repr(eb))


def _stream(m: Motion) -> bytes:
    enc = mocapz.StreamEncoder(m, codec="quant")
    return enc.write(m.values) + enc.close()


@pytest.fixture(scope="module")
def files() -> dict[str, bytes]:
    bvh = mocapz.load(data_path("cmu/bvh/06_13.bvh")).slice(0, 1500)
    c3d = mocapz.load(data_path("other/markers/pyomeca/markers_analogs.c3d"))  # analogs and events
    return {
        "lossless (blocks)": mocapz.compress(bvh, codec="lossless"),
        "quant (seekable)": mocapz.compress(bvh, codec="quant"),
        "pga (seekable)": mocapz.compress(bvh, codec="pga"),
        "patterns, 2-s blocks": mocapz.compress(bvh, codec="patterns", block="2s"),
        "quant, short clip": mocapz.compress(bvh.slice(0, 300), codec="quant"),
        "c3d with extras": mocapz.compress(replace(c3d, positions=c3d.positions[:400].copy()), codec="quant",
                                           block=100),
        "stream": _stream(bvh.slice(0, 700)),
    }


@pytest.mark.parametrize("name", ["lossless (blocks)", "quant (seekable)", "pga (seekable)",
                                  "patterns, 2-s blocks", "quant, short clip", "c3d with extras", "stream"])
def test_every_range_is_the_one_decompress_gives(files: dict[str, bytes], name: str) -> None:
    data = files[name]
    reader = mocapz.open(data)
    full = mocapz.decompress(data)
    n = len(reader)
    assert n == reader.n_frames == _values(full).shape[0] and reader.frame_rate == full.frame_rate
    rng = np.random.default_rng(3)
    for a in [0, n - 1, *rng.integers(0, n - 1, 6).tolist()]:
        b = int(min(n, a + rng.integers(1, 40)))
        part = reader[a:b]
        assert _same(part, mocapz.decompress(data, frames=slice(a, b))), (name, a, b)
        assert np.array_equal(_values(part), _values(full)[a:b], equal_nan=True), (name, a, b)
    assert _same(reader.read(), full) and _same(reader[:], full)


def test_a_path_is_read_once_and_errors_name_it(tmp_path, files: dict[str, bytes]) -> None:
    path = tmp_path / "clip.mcz"
    path.write_bytes(files["quant (seekable)"])
    reader = mocapz.open(path)
    assert reader.codec == "quant" and reader.path == str(path)
    path.unlink()  # the reader holds the bytes: the file is not read again
    assert _values(reader[10:30]).shape[0] == 20
    with pytest.raises(FormatError, match="clip.mcz.*cannot read"):
        mocapz.open(path)
    damaged = bytearray(files["quant (seekable)"])
    damaged[len(damaged) // 2] ^= 0x40
    path.write_bytes(bytes(damaged))
    with pytest.raises(FormatError, match="clip.mcz"):  # checked when opened, not at the first range
        mocapz.open(path)
    with pytest.raises(TypeError, match="slice"):
        mocapz.open(files["quant (seekable)"])[5]
    with pytest.raises(OptionError, match="select no frame"):
        mocapz.open(files["quant (seekable)"]).read((30, 10))


@pytest.mark.parametrize("name", ["lossless (blocks)", "quant (seekable)", "stream"])
def test_blocks_one_by_one_join_to_the_range(files: dict[str, bytes], name: str) -> None:
    reader = mocapz.open(files[name])
    pieces = list(reader.iter_blocks(slice(130, 560)))
    assert all(total == 430 for total, _ in pieces) and (len(pieces) > 1) == (name != "quant (seekable)")
    joined = np.concatenate([_values(m) for _, m in pieces])
    assert np.array_equal(joined, _values(reader[130:560]), equal_nan=True)


def _longer(m: MarkerMotion, frames: int) -> MarkerMotion:
    """A marker clip played forth and back to ``frames`` frames (a long take, coded with the seekable layout)."""
    pos = m.positions
    loop = np.concatenate([pos, pos[::-1]])
    reps = -(-frames // len(loop))
    return replace(m, positions=np.concatenate([loop] * reps)[:frames].copy())


@pytest.mark.parametrize("name", ["quant (seekable)", "pga (seekable)", "patterns markers (seekable)"])
def test_a_reader_keeps_what_its_windows_share(files: dict[str, bytes], name: str) -> None:
    """A reader read many times keeps what the windows of a clip in one block share (the running values' chunks
    decoded so far, a model's streams): windows in any order, repeated, overlapping or spanning chunks, give
    the full decode's rows to the bit, as a reader read once (``decompress(frames=)``, which keeps nothing)."""
    if name.startswith("patterns markers"):
        c3d = mocapz.load(data_path("other/markers/btkdata/Gait.trc"))
        data = mocapz.compress(_longer(c3d, 1300), codec="patterns")
    else:
        data = files[name]
    full = _values(mocapz.decompress(data))
    n = full.shape[0]
    rng = np.random.default_rng(8)
    ranges = [(int(a), int(min(n, a + rng.integers(1, 700)))) for a in rng.integers(0, n - 1, 14)]
    ranges += [ranges[3], (n - 1, n), (0, 1), ranges[0]]
    for order in (ranges, ranges[::-1]):
        reader = mocapz.open(data)
        for a, b in order:
            assert _values(reader[a:b]).tobytes() == full[a:b].tobytes(), (name, a, b)  # every bit
        assert reader._memo  # what the windows share was kept
    once = mocapz.Reader(data, keep=False)
    assert np.array_equal(_values(once[5:25]), full[5:25], equal_nan=True) and once._memo is None
