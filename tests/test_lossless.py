"""Lossless codec: exact round trip of every shared clip, determinism, CMU ratio guard, edge cases, and the
integer representations and entropy coder it is built on."""

from __future__ import annotations

import importlib.util
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA, data_path, first_block_sections

import mocapz
from mocapz import MarkerMotion, Motion, OptionError
from mocapz.codecs.lossless.integers import (
    REP_DECIMAL,
    REP_F32_DECIMAL,
    REP_F32_QUANTUM,
    REP_FLOAT32,
    REP_FLOAT64,
    REP_QUANTUM,
)
from mocapz.format.container import Container
from mocapz.format.entropy import (
    CODER_RANGE,
    CODER_RANGE_DELTA,
    CODER_ZSTD,
    HAVE_CONSTRICTION,
    LIMIT,
    decode_int_matrix,
    encode_int_matrix,
    pack_uint64,
    read_uvarint,
    unpack_uint64,
    unzigzag,
    write_uvarint,
    zigzag,
)
from mocapz.io.bvh import read_bvh
from mocapz.model.skeleton import Skeleton

MOTION_SUFFIXES = (".bvh", ".amc", ".c3d", ".trc")
SAMPLES_DIR = "other/markers/btkdata/c3d_samples"  # C3D storage variants and bad input (MANIFEST)
ALL_FILES = sorted(str(p.relative_to(DATA)) for p in DATA.rglob("*") if p.suffix.lower() in MOTION_SUFFIXES)
SHARED = [r for r in ALL_FILES if not r.startswith(SAMPLES_DIR)]
SAMPLES = [r for r in ALL_FILES if r.startswith(SAMPLES_DIR)]
BROKEN_SAMPLES = {"Empty.c3d", "bad_parameter_section.c3d"}  # bad-input material: must be refused cleanly
UNREAD_SAMPLES: dict[str, str] = {}  # readable files mocapz does not read yet (issue 10): strict xfail
CMU_BVH = sorted(str(p.relative_to(DATA)) for p in DATA.glob("cmu/bvh/*.bvh"))
READER = {".bvh": "mocapz.io.bvh", ".amc": "mocapz.io.amc", ".c3d": "mocapz.io.c3d", ".trc": "mocapz.io.trc"}
MIN_CMU_RATIO = 3.3  # measured 3.41 (every clip >= 3.0: test_lossless_values.py): guards against regressions


@cache
def _load(rel: str) -> Motion | MarkerMotion:
    """Load a shared clip once per session (skipping marker formats whose reader is not written yet)."""
    module = READER[Path(rel).suffix.lower()]
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} (the reader of {Path(rel).suffix} files) does not exist yet")
    return mocapz.load(data_path(rel))


@cache
def _packed(rel: str) -> bytes:
    """Lossless .mcz bytes of a shared clip, computed once per session."""
    return mocapz.compress(_load(rel), codec="lossless")


def _rep(data: bytes) -> int:
    """The value representation the lossless codec chose (its ``rep`` section)."""
    return first_block_sections(data)["rep"][0]


def assert_same_motion(a: Motion | MarkerMotion, b: Motion | MarkerMotion) -> None:
    """Exact equality of values (and gap masks), layout and clip information."""
    assert type(a) is type(b)
    assert b.frame_rate == a.frame_rate and b.name == a.name and b.source_format == a.source_format
    if isinstance(a, Motion):
        assert isinstance(b, Motion)
        assert b.channels.shape == a.channels.shape and np.array_equal(b.channels, a.channels)
        sa, sb = a.skeleton, b.skeleton
        assert sb.names == sa.names and np.array_equal(sb.parents, sa.parents)
        assert np.array_equal(sb.offsets, sa.offsets) and np.array_equal(sb.axis, sa.axis)
        assert sb.channels == sa.channels and sb.rotation_order == sa.rotation_order
        assert sb.angle_unit == sa.angle_unit and sb.unit_cm == sa.unit_cm
        assert len(sb.end_sites) == len(sa.end_sites)
        assert all(ja == jb and na == nb and np.array_equal(oa, ob)
                   for (ja, oa, na), (jb, ob, nb) in zip(sa.end_sites, sb.end_sites, strict=True))
        if a.decimals is None:
            assert b.decimals is None
        else:
            assert np.array_equal(b.decimals, a.decimals)
    else:
        assert isinstance(b, MarkerMotion)
        assert b.positions.shape == a.positions.shape
        assert np.array_equal(b.missing, a.missing)
        assert np.array_equal(b.positions, a.positions, equal_nan=True)
        assert b.labels == a.labels and b.units == a.units


# ------------------------------------------------------------------------------------- shared clips
def test_shared_clips_are_all_here() -> None:
    kinds = {Path(r).suffix.lower() for r in SHARED}
    assert kinds == set(MOTION_SUFFIXES) and len(SHARED) == 31 and len(CMU_BVH) == 14


@pytest.mark.parametrize("rel", SHARED)
def test_round_trip_every_shared_clip(rel: str) -> None:
    m = _load(rel)
    data = _packed(rel)
    assert data[:4] == b"MCZ\x1a"
    assert_same_motion(m, mocapz.decompress(data))
    assert mocapz.compress(m, codec="lossless") == data  # deterministic
    rep = _rep(data)
    if rel.endswith(".c3d"):
        assert rep in (REP_FLOAT32, REP_QUANTUM, REP_F32_QUANTUM)  # float32, or integers times a scale
    elif rel.startswith("cmu/bvh/"):
        assert rep == REP_DECIMAL


def _sample_params() -> list:
    return [pytest.param(r, marks=pytest.mark.xfail(strict=True, raises=mocapz.FormatError,
                                                     reason=f"issue 10: {UNREAD_SAMPLES[Path(r).name]}"))
            if Path(r).name in UNREAD_SAMPLES else r for r in SAMPLES]


@pytest.mark.parametrize("rel", _sample_params())
def test_c3d_samples(rel: str) -> None:
    """Every C3D storage variant comes back with the same values; broken files give a FormatError."""
    name = Path(rel).name
    if name in BROKEN_SAMPLES:
        with pytest.raises(mocapz.FormatError, match=name):
            mocapz.load(data_path(rel))
        return
    m = _load(rel)
    assert_same_motion(m, mocapz.decompress(_packed(rel)))


def test_cmu_bvh_ratio() -> None:
    """Total raw_bytes / total compressed bytes over cmu/bvh/*.bvh."""
    raw = sum(_load(rel).raw_bytes for rel in CMU_BVH)
    packed = sum(len(_packed(rel)) for rel in CMU_BVH)
    ratio = raw / packed
    assert ratio >= MIN_CMU_RATIO, f"lossless CMU ratio {ratio:.3f} < {MIN_CMU_RATIO}"


def test_evaluate_is_zero_on_markers() -> None:
    rel = "cmu/c3d/01_01.c3d"
    m = _load(rel)
    rep = mocapz.evaluate(m, mocapz.decompress(_packed(rel)))
    assert rep.distortion_pct == 0.0 and rep.max_err == 0.0


# ---------------------------------------------------------------------------------------- edge cases
def _skeleton(n_channels: int = 6) -> Skeleton:
    """A root with ``n_channels`` channels (positions then ZXY rotations) and one 3-channel child."""
    root = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")[:n_channels]
    return Skeleton(
        names=["root", "child"],
        parents=np.array([-1, 0]),
        offsets=np.array([[0.0, 0, 0], [0, 1.5, 0]]),
        channels=[root, ("Zrotation", "Xrotation", "Yrotation")],
        rotation_order=["".join(c[0] for c in root if c.endswith("rotation")), "ZXY"],
        end_sites=[(1, np.array([0.0, 1, 0]), "child_End")],
    )


def _round_trip(m: Motion | MarkerMotion) -> bytes:
    """Compress, check the exact round trip and determinism, return the bytes."""
    data = mocapz.compress(m, codec="lossless")
    assert_same_motion(m, mocapz.decompress(data))
    assert mocapz.compress(m, codec="lossless") == data
    return data


@pytest.mark.parametrize("frames", [0, 1, 2, 3, 4, 5, 257, 600])
def test_any_frame_count(frames: int) -> None:
    rng = np.random.default_rng(frames)
    ch = np.round(np.cumsum(rng.normal(size=(frames, 9)), axis=0), 3)
    _round_trip(Motion(_skeleton(), ch, 30.0, decimals=np.full(9, 3)))
    _round_trip(Motion(_skeleton(), ch, 30.0))  # decimals unknown
    real = read_bvh(data_path("cmu/bvh/09_06.bvh")).slice(0, frames)
    _round_trip(real)


def test_constant_columns() -> None:
    ch = np.zeros((50, 9))
    ch[:, 4] = np.linspace(0, 10, 50).round(2)
    _round_trip(Motion(_skeleton(), ch, 30.0, decimals=np.full(9, 2)))
    _round_trip(Motion(_skeleton(), np.full((50, 9), 3.25), 30.0, decimals=np.full(9, 2)))  # all constant


def test_float64_values_are_bit_exact() -> None:
    rng = np.random.default_rng(3)
    ch = rng.normal(size=(100, 9)) * 10.0 ** rng.integers(-8, 8, size=9)
    ch[5, 2] = -0.0
    ch[6, 3] = 5e-324  # subnormal
    ch[7, 4] = 1.7976931348623157e308
    m = Motion(_skeleton(), ch, 30.0)
    data = _round_trip(m)
    assert _rep(data) == REP_FLOAT64
    back = mocapz.decompress(data)
    assert back.channels.view(np.int64).tolist() == ch.view(np.int64).tolist()  # -0.0 keeps its sign


def test_wrong_decimals_fall_back_to_exact() -> None:
    """Claimed decimals that do not represent the values exactly must not lose precision."""
    ch = np.array([[0.123456] * 9, [0.5] * 9, [1.25] * 9])
    data = _round_trip(Motion(_skeleton(), ch, 30.0, decimals=np.full(9, 2)))
    sections = Container.from_bytes(data).sections
    assert _rep(data) != REP_DECIMAL or "exc" in sections  # off-decimal values: exceptions, never rounded


def test_large_jumps_use_escapes() -> None:
    """Residuals beyond the range coder's alphabet (|r| >= 32767) are escaped and come back exactly."""
    ch = np.zeros((40, 9))
    ch[10, 0] = 1e6
    ch[20, 5] = -123456.789
    ch[30:, 8] = 99999.999
    _round_trip(Motion(_skeleton(), ch, 30.0, decimals=np.full(9, 3)))


def test_root_with_three_channels_and_radians() -> None:
    sk = _skeleton(3)
    sk.angle_unit = "rad"
    ch = np.round(np.random.default_rng(5).normal(size=(30, 6)), 5)
    _round_trip(Motion(sk, ch, 24.0, decimals=np.full(6, 5)))


def _markers(frames: int, n: int, seed: int = 0) -> np.ndarray:
    """Smooth random marker trajectories ``(frames, n, 3)`` rounded to float32."""
    rng = np.random.default_rng(seed)
    pos = np.cumsum(rng.normal(size=(frames, n, 3)), axis=0) * 10 + 500
    return pos.astype(np.float32).astype(np.float64)


def test_markers_with_gaps() -> None:
    pos = _markers(120, 5)
    pos[:10, 0] = np.nan  # leading gap
    pos[50:70, 1] = np.nan  # inner gap
    pos[110:, 2] = np.nan  # trailing gap
    pos[:, 3] = np.nan  # never seen
    pos[60, 4, 1] = np.nan  # one coordinate only
    m = MarkerMotion([f"M{i}" for i in range(5)], pos, 100.0, units="mm", source_format="trc")
    data = _round_trip(m)
    assert _rep(data) == REP_FLOAT32 and "gaps" in Container.from_bytes(data).sections
    assert "exc" not in Container.from_bytes(data).sections


def test_markers_without_gaps_and_with_decimals() -> None:
    pos = np.round(_markers(60, 3, seed=2), 3)
    m = MarkerMotion(["a", "b", "c"], pos, 60.0, units="m", decimals=3, source_format="trc")
    data = _round_trip(m)
    assert _rep(data) in (REP_DECIMAL, REP_F32_DECIMAL) and "gaps" not in Container.from_bytes(data).sections
    _round_trip(MarkerMotion(["a"], np.full((1, 1, 3), np.nan), 60.0))  # one frame, all missing


def test_markers_without_frames() -> None:
    _round_trip(MarkerMotion(["a", "b"], np.zeros((0, 2, 3)), 60.0))


def test_single_frame_float64() -> None:
    """One frame of values kept as float64 bit patterns (decimals unknown) must come back bit for bit."""
    ch = np.array([[0.346, 0.822, 0.33, -1.303, 0.905, 0.446, -0.537, 0.581, 0.365]])
    _round_trip(Motion(_skeleton(), ch, 30.0))


def test_lossless_takes_no_options() -> None:
    m = Motion(_skeleton(), np.zeros((3, 9)), 30.0)
    with pytest.raises(OptionError, match="no options"):
        mocapz.compress(m, codec="lossless", bits=8)


def test_unknown_codec_is_an_option_error() -> None:
    with pytest.raises(OptionError, match="unknown codec"):
        mocapz.compress(Motion(_skeleton(), np.zeros((3, 9)), 30.0), codec="nosuch")


# ------------------------------------------------------------------------------------ entropy coding
@pytest.mark.parametrize("value", [0, 1, 127, 128, 300, 2**32, 2**63 - 1])
def test_uvarint(value: int) -> None:
    enc = write_uvarint(value)
    assert read_uvarint(enc + b"tail", 0) == (value, len(enc))
    assert len(enc) == max(1, -(-value.bit_length() // 7))


def test_uvarint_examples_and_errors() -> None:
    assert write_uvarint(300) == b"\xac\x02"
    with pytest.raises(ValueError):
        write_uvarint(-1)
    with pytest.raises(mocapz.FormatError):
        read_uvarint(b"\x80\x80", 0)
    with pytest.raises(mocapz.FormatError):
        read_uvarint(b"\xff" * 12, 0)


def test_zigzag() -> None:
    v = np.array([0, -1, 1, -2, 2, 2**62, -(2**63), 2**63 - 1], dtype=np.int64)
    z = zigzag(v)
    assert z[:5].tolist() == [0, 1, 2, 3, 4]
    assert np.array_equal(unzigzag(z), v)


def test_pack_uint64() -> None:
    for values in ([], [0], [5, 255, 0], [256, 1], [2**64 - 1, 0, 7]):
        u = np.array(values, dtype=np.uint64)
        packed = pack_uint64(u)
        assert np.array_equal(unpack_uint64(packed), u)
    packed = pack_uint64(np.array([1, 2, 3], dtype=np.uint64))
    assert packed[:2] == b"\x03\x01"  # count, then bytes per value


def test_large_streams_keep_no_compressor(monkeypatch: pytest.MonkeyPatch) -> None:
    """A stream of megabytes is packed by a zstd context of megabytes that is not kept for the rest of the
    process (resident memory), small ones are kept; a kept context packs the bytes a new one packs."""
    import threading

    from mocapz.format import planes

    rng = np.random.default_rng(3)
    small = rng.integers(0, 50, 2_000).astype(np.uint64)
    large = rng.integers(0, 50, 400_000).astype(np.uint64)  # 3.2 MB: level 19's tables of 2**21 entries
    out: dict[int, tuple[list[bytes], dict]] = {}

    def run(keep: int) -> None:  # a thread of its own: its compressors start empty
        monkeypatch.setattr(planes, "KEEP_LOG", keep)
        out[keep] = [pack_uint64(v) for v in (small, large, small, large)], dict(planes._LOCAL.zstd)

    default = planes.KEEP_LOG
    for keep in (default, 30):
        t = threading.Thread(target=run, args=(keep,))
        t.start()
        t.join()
    packed, kept = out[default]
    assert kept and all(max(key[:3]) <= default for key in kept)
    every_packed, every_kept = out[30]
    assert any(max(key[:3]) > default for key in every_kept)  # the large one kept and used twice
    assert packed == every_packed and packed[0] == packed[2] and packed[1] == packed[3]


MATRICES = {
    "empty-rows": np.zeros((0, 4), dtype=np.int64),
    "empty-cols": np.zeros((5, 0), dtype=np.int64),
    "one": np.array([[7]]),
    "laplace": np.random.default_rng(0).laplace(scale=30, size=(700, 6)).round().astype(np.int64),
    "escapes": np.array([[0, LIMIT - 1], [LIMIT, -LIMIT], [10**12, -(10**15)], [3, 2**62]], dtype=np.int64),
    "zeros": np.zeros((300, 3), dtype=np.int64),
    "column": np.arange(-50, 50, dtype=np.int64)[:, None],
}


@pytest.mark.parametrize("name", list(MATRICES))
@pytest.mark.parametrize("coder", [CODER_RANGE, CODER_RANGE_DELTA, CODER_ZSTD])
def test_int_matrix_round_trip(name: str, coder: int) -> None:
    if coder != CODER_ZSTD and not HAVE_CONSTRICTION:
        pytest.skip("constriction is not installed (no wheel on this platform)")
    v = MATRICES[name]
    data = encode_int_matrix(v, coder=coder)
    assert data[0] == (CODER_ZSTD if v.size == 0 else coder)
    rows, pos = read_uvarint(data, 1)
    cols, pos = read_uvarint(data, pos)
    assert (rows, cols) == v.shape
    back = decode_int_matrix(data)
    assert back.shape == v.shape and np.array_equal(back, v)


def test_range_stream_layout() -> None:
    """Coder byte, rows, cols, the scale model's byte, escapes, uint32 body (the scale codes first in it)."""
    if not HAVE_CONSTRICTION:
        pytest.skip("constriction is not installed")
    v = MATRICES["laplace"]  # 700 rows -> 3 blocks x 6 columns
    data = encode_int_matrix(v)
    assert data[0] == CODER_RANGE_DELTA
    head = write_uvarint(700) + write_uvarint(6)
    assert data[1 : 1 + len(head)] == head
    pos = 1 + len(head) + 1
    assert data[pos] == 0  # no escapes
    n_body, body_at = read_uvarint(data, pos + 1)
    assert body_at + n_body == len(data) and n_body % 4 == 0
    # the scale codes follow the mean absolute value: s = 2 ** ((q - 32) / 4) ~ 30 for a Laplace of scale 30
    from mocapz.format.entropy import _quarter_scales

    q = _quarter_scales(v)
    assert q.shape == (3, 6) and np.allclose(2.0 ** ((q - 32) / 4), 30, rtol=0.25)
    # their differences cost a few bits each, less than a byte per scale (CODER_RANGE), on this matrix and on
    # a 1-s block's 96 columns of smoothly growing scales (3.88 vs 3.885 kB, 21.84 vs 21.91 kB measured)
    assert len(data) < len(encode_int_matrix(v, CODER_RANGE))
    block = np.random.default_rng(1).laplace(scale=1, size=(240, 96)).round().astype(np.int64) * np.arange(1, 97)
    assert len(encode_int_matrix(block)) + 48 < len(encode_int_matrix(block, CODER_RANGE))


@pytest.mark.parametrize("junk", [b"", b"\x01", b"\x01\x02", b"\x09\x01\x01\x00", b"\x01\x05\x02\x40",
                                  b"\x02\x03\x02\x06", b"\x01\xff\xff\xff\xff\xff\xff\xff\x7f\x01abc"])
def test_int_matrix_garbage(junk: bytes) -> None:
    with pytest.raises(mocapz.FormatError):
        decode_int_matrix(junk)


def test_int_matrix_corrupted_body() -> None:
    """Random corruption of a range-coded stream: FormatError or some matrix of the right shape."""
    if not HAVE_CONSTRICTION:
        pytest.skip("constriction is not installed")
    v = MATRICES["laplace"][:300]
    data = encode_int_matrix(v)
    rng = np.random.default_rng(11)
    for _ in range(200):
        b = bytearray(data)
        i = int(rng.integers(0, len(b)))
        b[i] ^= int(rng.integers(1, 256))
        try:
            out = decode_int_matrix(bytes(b))
        except mocapz.FormatError:
            continue
        assert out.ndim == 2


def test_index_lists_packed_fast_for_hardly_more_bytes(monkeypatch: pytest.MonkeyPatch) -> None:
    """The index lists (a cgspeed BVH's thousands of "-0.000000" values) are zstd-packed at INDEX_LEVEL, not
    19: a fifth of the lossless encode's time, for at most 0.1 % of the file (0.02 % measured on 06_13)."""
    from mocapz.codecs.lossless import coding

    m = mocapz.load(data_path("cmu/bvh/06_13.bvh")).slice(0, 1200)
    fast = mocapz.compress(m, "lossless")
    assert coding.INDEX_LEVEL < 19
    assert "negz" in first_block_sections(fast)  # the lists are there
    monkeypatch.setattr(coding, "INDEX_LEVEL", 19)
    slow = mocapz.compress(m, "lossless")
    assert len(slow) <= len(fast) <= 1.001 * len(slow)
    assert np.array_equal(mocapz.decompress(fast).values, m.values)


@pytest.mark.parametrize("rel", ["cmu/bvh/09_06.bvh", "cmu/c3d/01_01.c3d"])
def test_exact_copy_figures_are_evaluate_figures(rel: str) -> None:
    """A lossless round trip's error figures without positions (what ``mocapz compress`` prints) are
    :func:`evaluate`'s; one value changed, or another kind, and they are not taken."""
    from mocapz.metrics.figures import evaluate, exact_copy

    m = mocapz.load(data_path(rel)).slice(0, 300)
    back = mocapz.decompress(mocapz.compress(m, "lossless"))
    rep, full = exact_copy(m, back), evaluate(m, back)
    assert rep is not None
    for name in ("distortion_pct", "arms", "max_err", "p99_err", "bone_len_err", "unit_cm", "frames", "points"):
        assert getattr(rep, name) == getattr(full, name)
    values = back.values.copy()
    values[100, 0, ...] = np.nextafter(values[100, 0, ...], np.inf)  # one value a float's last bit off
    changed = back.with_values(values)
    assert exact_copy(m, changed) is None and evaluate(m, changed).max_err > 0
