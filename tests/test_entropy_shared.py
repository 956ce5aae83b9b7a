"""Integer streams whose column groups share their Laplace scales (coder 5, :mod:`mocapz.format.entropy_shared`):
exact round trips, what the decoder needs, damaged streams, and the bytes they save on a real short clip's
correction (its lifting levels of 8 to 64 rows, where a scale per column costs a third of the stream)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import mocapz
from mocapz.codecs.correction import lifting
from mocapz.codecs.correction.wrap import group_of
from mocapz.errors import FormatError
from mocapz.format import entropy, entropy_shared
from mocapz.format.entropy_shared import CODER_RANGE_SHARED, decode_int_matrix, encode_int_matrix

pytest.importorskip("constriction")

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def _joint_like(rows: int, groups: np.ndarray, seed: int) -> np.ndarray:
    """Laplace integers whose scale is a group's (1/8 to 64), the same for the columns of a group."""
    rng = np.random.default_rng(seed)
    scale = 2.0 ** rng.uniform(-3, 6, groups.max() + 1)[groups]
    return np.round(rng.laplace(0, scale, (rows, groups.size))).astype(np.int64)


@pytest.mark.parametrize(("rows", "seed"), [(1, 0), (7, 1), (40, 2), (255, 3), (256, 4), (700, 5)])
def test_round_trip_and_shared_scales_win_on_groups(rows: int, seed: int) -> None:
    groups = np.repeat(np.arange(11), 3)
    v = _joint_like(rows, groups, seed)
    shared = entropy_shared.encode(v, groups)
    assert shared[0] == CODER_RANGE_SHARED
    np.testing.assert_array_equal(decode_int_matrix(shared, v.shape, groups), v)
    best = encode_int_matrix(v, groups)  # the smaller of the two
    np.testing.assert_array_equal(decode_int_matrix(best, v.shape, groups), v)
    per_column = entropy.encode_int_matrix(v)
    assert len(best) <= len(per_column)
    np.testing.assert_array_equal(decode_int_matrix(per_column, v.shape, groups), v)  # both kinds read
    if rows <= 64:  # few rows: the scales are a large share, a third of them is the smaller stream
        assert best[0] == CODER_RANGE_SHARED and len(best) < len(per_column)


def test_escapes_zeros_and_any_labels() -> None:
    groups = np.array([7, 7, -2, 40, 40, 40])  # any labels, a scale per distinct one
    v = np.zeros((30, 6), dtype=np.int64)
    v[3, 1], v[9, 4], v[20, 2] = 10**12, -(10**9), 5
    np.testing.assert_array_equal(decode_int_matrix(entropy_shared.encode(v, groups), v.shape, groups), v)


def test_the_decoder_needs_the_encoders_groups() -> None:
    groups = np.repeat(np.arange(4), 3)
    v = _joint_like(20, groups, 9)
    data = entropy_shared.encode(v, groups)
    with pytest.raises(FormatError, match="coder id 5"):  # the plain reader does not take it
        entropy.decode_int_matrix(data, v.shape)
    with pytest.raises(FormatError, match="shape"):
        decode_int_matrix(data, (v.shape[0] + 1, v.shape[1]), groups)
    with pytest.raises(FormatError, match="column groups"):
        decode_int_matrix(data, v.shape, groups[:-1])


def test_damaged_streams_are_format_errors() -> None:
    groups = np.repeat(np.arange(5), 3)
    v = _joint_like(50, groups, 4)
    data = bytearray(entropy_shared.encode(v, groups))
    head = 1 + 1 + 1  # coder, rows (50), cols (15): one byte each
    bad_pick = data.copy()
    bad_pick[head] = 200
    with pytest.raises(FormatError):
        decode_int_matrix(bytes(bad_pick), v.shape, groups)
    with pytest.raises(FormatError):
        decode_int_matrix(bytes(data[:-4]), v.shape, groups)
    rng = np.random.default_rng(0)
    for _ in range(30):  # flipped bytes: an error or some matrix, never a crash
        d = data.copy()
        d[int(rng.integers(head + 1, len(d)))] ^= int(rng.integers(1, 256))
        try:
            out = decode_int_matrix(bytes(d), v.shape, groups)
        except FormatError:
            continue
        assert out.shape == v.shape


@pytest.mark.parametrize(("clip", "at_most"), [("cmu/bvh/02_05.bvh", 0.95), ("cmu/asfamc/lambada.amc", 0.99),
                                              ("other/markers/btkdata/Gait.trc", 0.995)])
def test_a_streams_blocks_share_their_joints_scales(clip: str, at_most: float, monkeypatch: pytest.MonkeyPatch
                                                    ) -> None:
    """The blocks of a real stream (a second each: lifting levels of 4 to 64 rows; a skeleton with 3- and
    6-channel joints, ASF joints of 1 to 3 degrees of freedom, markers): every correction stream packed with the
    header's groups decodes to its integers, is never larger than with a scale per column, and all of them
    together are smaller (measured over the encoder's trials, first 640 frames: 02_05 -9.7 %, lambada -3.0 %,
    Gait -1.0 %: marker x, y and z move less alike than a joint's angles)."""
    path = DATA / clip
    if not path.exists():
        pytest.skip(f"{path} not found")
    m = mocapz.load(path).slice(0, 640)
    calls = []
    pack = lifting.pack

    def spy(q, frames, levels, prefix=None, groups=None):  # noqa: ANN001, ANN202
        calls.append((q, frames, levels, prefix, groups))
        return pack(q, frames, levels, prefix, groups)

    monkeypatch.setattr(lifting, "pack", spy)
    enc = mocapz.StreamEncoder(m, codec="quant", max_error="1cm")
    data = enc.write(m.values) + enc.close()
    box, header = mocapz.api.read_container(data)
    np.testing.assert_array_equal(calls[-1][4], group_of(header))  # the encoder's groups are the decoder's
    shared = per_column = 0
    for q, frames, levels, prefix, groups in calls:
        assert groups is not None
        a, b = pack(q, frames, levels, prefix, groups), pack(q, frames, levels, prefix)
        np.testing.assert_array_equal(lifting.read(a, frames, q.shape[1], levels, prefix, groups), q)
        assert len(a) <= len(b)
        shared, per_column = shared + len(a), per_column + len(b)
    assert shared < at_most * per_column, (shared, per_column)
    assert mocapz.decompress(data).n_frames == m.n_frames
