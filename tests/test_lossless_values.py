"""Lossless means every value back bit for bit (the sign of zero included), whatever wrote the numbers, and a
file never larger than ``xz -9e`` of its source: every shared and sample file, a mixed-precision BVH made
here from a clean one (trailing zeros cut, ``-0.0000``, a float artefact), and the writers."""

from __future__ import annotations

import bz2
import lzma
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA, data_path, first_block_sections

import mocapz
from mocapz import MarkerMotion, Motion
from mocapz.io.amc import read_asfamc, write_asfamc
from mocapz.io.bvh import read_bvh, write_bvh
from mocapz.io.trc import read_trc, write_trc

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from lossless import mixed_precision  # noqa: E402  (the rewrite the benchmark measures too)

SUFFIXES = (".bvh", ".amc", ".c3d", ".trc")
ALL_FILES = sorted(str(p.relative_to(DATA)) for p in DATA.rglob("*") if p.suffix.lower() in SUFFIXES)
UNREADABLE = {"Empty.c3d", "bad_parameter_section.c3d"}  # bad-input material (test_lossless.py)
READABLE = [r for r in ALL_FILES if Path(r).name not in UNREADABLE]
CMU_BVH = sorted(str(p.relative_to(DATA)) for p in DATA.glob("cmu/bvh/*.bvh"))
MIN_RATIO = 3.0  # against float32, every cgspeed CMU BVH


def bits(values: np.ndarray) -> np.ndarray:
    """The float64 bit patterns (NaN gaps as one pattern), so ``-0`` and ``+0`` differ."""
    v = np.where(np.isnan(values), np.nan, values)
    return np.ascontiguousarray(v, dtype=np.float64).view(np.int64)


def assert_bit_exact(a: Motion | MarkerMotion, b: Motion | MarkerMotion) -> None:
    assert a.values.shape == b.values.shape
    assert np.array_equal(bits(a.values), bits(b.values))


def source_bytes(rel: str) -> bytes:
    """The source file's bytes (an AMC with its ASF skeleton)."""
    path = data_path(rel)
    if path.suffix.lower() == ".amc":
        from mocapz.io.asf import find_asf

        return path.read_bytes() + find_asf(path).read_bytes()
    return path.read_bytes()


@cache
def _load(rel: str) -> Motion | MarkerMotion:
    return mocapz.load(data_path(rel))


@cache
def _packed(rel: str) -> bytes:
    return mocapz.compress(_load(rel), codec="lossless")


def bzip2_baseline(motion: Motion, decimals: int = 4) -> int:
    """Bytes of the few-line baseline: second differences of the ``10**-decimals`` integers, channel by
    channel (int64 little endian), through bzip2 -9 (as scripts/lossless.py measures it)."""
    x = np.round(motion.channels * 10.0**decimals).astype(np.int64)
    d = np.concatenate([x[:2], x[2:] - 2 * x[1:-1] + x[:-2]]) if len(x) > 2 else x
    return len(bz2.compress(np.ascontiguousarray(d.T).astype("<i8").tobytes(), 9))


@pytest.mark.parametrize("rel", READABLE)
def test_every_file_bit_exact_and_under_xz(rel: str) -> None:
    m = _load(rel)
    data = _packed(rel)
    assert_bit_exact(m, mocapz.decompress(data))
    xz = len(lzma.compress(source_bytes(rel), preset=9 | lzma.PRESET_EXTREME))
    assert len(data) <= xz, f"{rel}: .mcz {len(data)} B > xz -9e {xz} B"


@pytest.mark.parametrize("rel", CMU_BVH)
def test_cmu_bvh_ratio_and_baseline(rel: str) -> None:
    m = _load(rel)
    size = len(_packed(rel))
    assert m.raw_bytes / size >= MIN_RATIO
    assert size <= bzip2_baseline(m)


def test_zero_signs_kept_on_cmu() -> None:
    """09_06 holds 996 ``-0.0000``: they come back negative."""
    m = _load("cmu/bvh/09_06.bvh")
    neg = np.signbit(m.channels) & (m.channels == 0)
    assert neg.sum() == 996
    back = mocapz.decompress(_packed("cmu/bvh/09_06.bvh"))
    assert np.array_equal(np.signbit(back.channels), np.signbit(m.channels))


# ------------------------------------------------------------------------------- mixed-precision BVH
# mixed_precision: the rewrite scripts/lossless.py measures too (one definition, imported above)


@pytest.mark.parametrize("rel", ["cmu/bvh/09_06.bvh", "cmu/bvh/02_03.bvh"])
def test_mixed_precision_bvh(rel: str, tmp_path: Path) -> None:
    clean = _load(rel)
    path = tmp_path / Path(rel).name
    path.write_text(mixed_precision(data_path(rel).read_text()))
    m = read_bvh(path)
    assert int((np.signbit(m.channels) & (m.channels == 0)).sum()) > int(
        (np.signbit(clean.channels) & (clean.channels == 0)).sum())
    assert np.array_equal(m.decimals, clean.decimals)  # the common precision, despite the artefact
    data = mocapz.compress(m, codec="lossless")
    assert_bit_exact(m, mocapz.decompress(data))
    assert len(data) <= 1.05 * len(_packed(rel))
    assert m.raw_bytes / len(data) >= MIN_RATIO
    out = tmp_path / "back.bvh"
    write_bvh(mocapz.decompress(data), out)
    assert_bit_exact(m, read_bvh(out))


# ------------------------------------------------------------------------------------------ writers
def test_trc_writer_keeps_exceptions(tmp_path: Path) -> None:
    m = read_trc(data_path("other/markers/btkdata/Gait.trc"))
    pos = m.positions.copy()
    seen = np.argwhere(np.isfinite(pos))
    pos[tuple(seen[10])] = -0.0
    pos[tuple(seen[20])] += 1e-9  # off the 5 decimals
    odd = MarkerMotion(m.labels, pos, m.frame_rate, m.units, m.name, "trc", m.decimals, m.metadata)
    write_trc(odd, tmp_path / "g.trc")
    back = read_trc(tmp_path / "g.trc")
    assert back.decimals == m.decimals
    assert_bit_exact(odd, back)
    assert_bit_exact(odd, mocapz.decompress(mocapz.compress(back, codec="lossless")))


def test_amc_writer_keeps_exceptions(tmp_path: Path) -> None:
    m = read_asfamc(data_path("cmu/asfamc/01_01.amc")).slice(0, 200)
    ch = m.channels.copy()
    ch[5, 7] = -0.0
    ch[9, 10] = 1.0 / 3.0
    odd = m.with_channels(ch, m.decimals)
    write_asfamc(odd, tmp_path / "a.amc")
    back = read_asfamc(tmp_path / "a.amc")
    assert_bit_exact(odd, back)
    assert_bit_exact(odd, mocapz.decompress(mocapz.compress(back, codec="lossless")))


def test_lossy_values_are_still_rounded(tmp_path: Path) -> None:
    """A decoded lossy clip (most values off the decimals) is written at the source's decimals, no -0.0000."""
    m = _load("cmu/bvh/09_06.bvh").slice(0, 20)
    noisy = m.with_channels(m.channels + 1e-7 * np.arange(m.channels.size).reshape(m.channels.shape) - 3e-5,
                            m.decimals)
    write_bvh(noisy, tmp_path / "n.bvh")
    text = (tmp_path / "n.bvh").read_text().split("MOTION", 1)[1]
    assert "e-" not in text and "-0.0000 " not in text
    error = np.abs(read_bvh(tmp_path / "n.bvh").channels - noisy.channels)
    assert (error <= 0.5 * 10.0 ** -m.decimals.astype(float) + 1e-9).all()


# ---------------------------------------------------------------------------------- representations
def test_integer_c3d_codes_the_integers() -> None:
    """Values stored as integers times a scale (integer C3D) are coded as those integers when the motion says
    its quantum; an odd value among them is an exception, and -0 keeps its sign."""
    from mocapz.codecs.lossless.integers import REP_QUANTUM
    from mocapz.format.container import Container

    scale = float(np.float32(0.0833333358168602))
    rng = np.random.default_rng(4)
    ints = np.cumsum(np.cumsum(rng.integers(-3, 4, size=(300, 6, 3)), axis=0), axis=0) + 3000
    pos = ints.astype(np.float64) * scale
    pos[10:20, 2] = np.nan
    pos[50, 1, 0] = -0.0
    pos[60, 3, 2] += 1e-9  # not a multiple of the scale
    m = MarkerMotion([f"M{i}" for i in range(6)], pos, 60.0, "mm", "eb", "c3d")
    plain = mocapz.compress(m, codec="lossless", block=0)
    m.quantum = scale  # what the C3D reader reports for integer storage (MarkerMotion.quantum)
    data = mocapz.compress(m, codec="lossless", block=0)  # the codec's choices, in one block
    box = Container.from_bytes(data)
    assert box.sections["rep"][0] == REP_QUANTUM and "exc" in box.sections and "negz" in box.sections
    assert_bit_exact(m, mocapz.decompress(data))
    assert len(data) < 0.7 * len(plain)


def test_exceptions_cost_little() -> None:
    """One float artefact and a few -0 add a few bytes, not a representation change."""
    m = _load("cmu/bvh/09_06.bvh")
    ch = m.channels.copy()
    ch[70, 20] -= 1e-14  # like -0.0071 -> -0.00709999999999
    plus_zeros = np.argwhere((ch == 0) & ~np.signbit(ch))
    ch[tuple(plus_zeros[::50].T)] = -0.0
    odd = m.with_channels(ch, m.decimals)
    data = mocapz.compress(odd, codec="lossless")
    assert_bit_exact(odd, mocapz.decompress(data))
    assert len(data) <= len(_packed("cmu/bvh/09_06.bvh")) + 20 + 3 * len(plus_zeros[::50])


def test_float_c3d_from_integers_codes_the_integers() -> None:
    """float32 values written from integers times a scale (C3D REAL storage) are coded as those integers; the
    scale is found in the data."""
    from mocapz.codecs.lossless.integers import REP_F32_QUANTUM
    from mocapz.format.container import Container

    scale = float(np.float32(0.0833333358168602))
    rng = np.random.default_rng(5)
    ints = np.cumsum(np.cumsum(rng.integers(-3, 4, size=(300, 6, 3)), axis=0), axis=0) + 9000
    pos = (ints.astype(np.float64) * scale).astype(np.float32).astype(np.float64)
    pos[7, 2, 1] = np.float32(pos[7, 2, 1] + 0.01)  # a float32 off the grid: an exception
    m = MarkerMotion([f"M{i}" for i in range(6)], pos, 60.0, "mm", "eb", "c3d")
    data = mocapz.compress(m, codec="lossless", block=0)  # the codec's choices, in one block
    box = Container.from_bytes(data)
    assert box.sections["rep"][0] == REP_F32_QUANTUM and "exc" in box.sections
    assert_bit_exact(m, mocapz.decompress(data))


def test_per_column_precision() -> None:
    """%g text (AMC): each column gets its own representation; tiny values are exceptions."""
    from mocapz.codecs.lossless.integers import REP_COLUMNS

    m = _load("other/asfamc/amcparser/walking.amc")
    data = _packed("other/asfamc/amcparser/walking.amc")
    assert first_block_sections(data)["rep"][0] == REP_COLUMNS
    assert m.raw_bytes / len(data) > 1.9  # 1.51 with one representation for the clip
