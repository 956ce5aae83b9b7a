"""BVH reader and writer on every shared BVH file, forward kinematics against a per-frame reference, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import DATA, data_path
from scipy.spatial.transform import Rotation

from mocapz.errors import FormatError, MocapzError
from mocapz.io.bvh import read_bvh, write_bvh
from mocapz.io.common import CMU_UNIT_CM
from mocapz.model.kinematics import forward_kinematics
from mocapz.model.motion import Motion
from mocapz.model.skeleton import Skeleton

# (file, frames, joints, channels, end sites, frames per second) as listed in the data MANIFEST
BVH_FILES = [
    ("cmu/bvh/01_01.bvh", 2752, 31, 96, 7, 120.0),
    ("cmu/bvh/02_01.bvh", 344, 31, 96, 7, 120.0),
    ("cmu/bvh/02_03.bvh", 174, 31, 96, 7, 120.0),
    ("cmu/bvh/02_05.bvh", 1855, 31, 96, 7, 120.0),
    ("cmu/bvh/02_07.bvh", 2252, 31, 96, 7, 120.0),
    ("cmu/bvh/03_04.bvh", 4723, 31, 96, 7, 120.0),
    ("cmu/bvh/05_02.bvh", 1124, 31, 96, 7, 120.0),
    ("cmu/bvh/05_18.bvh", 1830, 31, 96, 7, 120.0),
    ("cmu/bvh/06_10.bvh", 1114, 31, 96, 7, 120.0),
    ("cmu/bvh/06_13.bvh", 4906, 31, 96, 7, 120.0),
    ("cmu/bvh/09_01.bvh", 149, 31, 96, 7, 120.0),
    ("cmu/bvh/09_06.bvh", 142, 31, 96, 7, 120.0),
    ("cmu/bvh/09_12.bvh", 1919, 31, 96, 7, 120.0),
    ("cmu/bvh/12_01.bvh", 524, 31, 96, 7, 120.0),
    ("cmu/bvh_iclone_ccrig/002_03.bvh", 86, 101, 306, 41, 60.0),
    ("other/bvh/bandai_namco/dataset-1_dance-short_normal_001.bvh", 1901, 22, 132, 5, 30.0),
    ("other/bvh/bandai_namco/dataset-1_walk_normal_001.bvh", 195, 22, 132, 5, 30.0),
    ("other/bvh/bandai_namco/dataset-1_punch_normal_001.bvh", 224, 22, 132, 5, 30.0),
    ("other/bvh/bandai_namco/dataset-2_walk_elderly_004.bvh", 466, 22, 132, 5, 30.0),
    ("other/bvh/games105/walk_and_turn_left.bvh", 420, 20, 63, 5, 100.0),
    ("other/bvh/games105/idle.bvh", 200, 20, 63, 5, 60.0),
    ("other/bvh/bvh-python/test_mocapbank.bvh", 455, 19, 60, 5, 30.0),
    ("other/bvh/pymo/AV_8Walk_Meredith_HVHA_Rep1.bvh", 1064, 23, 72, 7, 120.0),
]
BVH_IDS = [Path(f[0]).stem for f in BVH_FILES]

TINY_BVH = """HIERARCHY
ROOT Hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT Chest
\t{
\t\tOFFSET 0 10 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 5 0
\t\t}
\t}
}
MOTION
Frames: 2
Frame Time: 0.1
1.0 2.0 3.0 0.0 0.0 0.0 90.0 0.0 0.0
0.5 0.25 -1.0 10.0 20.0 30.0 -45.0 15.5 7.25
"""
TINY_LINES = TINY_BVH.splitlines()
FIRST_ROW_LINE = 19  # 1-based line number of the first MOTION row of TINY_BVH


def _write(tmp_path: Path, text: str, name: str = "bad.bvh") -> Path:
    """Write ``text`` to ``tmp_path/name`` and return the path."""
    p = tmp_path / name
    p.write_text(text)
    return p


def _reference_fk(sk: Skeleton, row: np.ndarray) -> np.ndarray:
    """Per-frame FK written independently of mocapz.model.kinematics: ``(joints + end sites, 3)`` positions.

    Each joint's local rotation is ``Rotation.from_euler(order.upper(), angles, degrees=True)`` (intrinsic
    rotations in the listed channel order, i.e. R = R_a1 @ R_a2 @ R_a3); position channels replace the
    matching OFFSET components.
    """
    g_rot: list[np.ndarray] = []
    g_pos: list[np.ndarray] = []
    col = 0
    for j, chs in enumerate(sk.channels):
        vals = dict(zip(chs, row[col : col + len(chs)], strict=True))
        col += len(chs)
        local_t = np.array(sk.offsets[j], dtype=np.float64)
        for k, axis in enumerate("XYZ"):
            if f"{axis}position" in vals:
                local_t[k] = vals[f"{axis}position"]
        order = "".join(c[0] for c in chs if c.endswith("rotation"))
        if order:
            angles = [vals[f"{a}rotation"] for a in order]
            local_r = Rotation.from_euler(order.upper(), angles, degrees=True).as_matrix()
        else:
            local_r = np.eye(3)
        p = int(sk.parents[j])
        if p < 0:
            g_rot.append(local_r)
            g_pos.append(local_t)
        else:
            g_rot.append(g_rot[p] @ local_r)
            g_pos.append(g_pos[p] + g_rot[p] @ local_t)
    ends = [g_pos[j] + g_rot[j] @ np.asarray(off) for j, off, _ in sk.end_sites]
    return np.array(g_pos + ends)


# ------------------------------------------------------------------------------------------- reading
def test_table_lists_every_shared_bvh() -> None:
    """Every BVH in the shared data is in BVH_FILES, so the tests below cover all of them."""
    found = {str(p.relative_to(DATA)) for p in DATA.glob("cmu/**/*.bvh")} | {
        str(p.relative_to(DATA)) for p in DATA.glob("other/**/*.bvh")
    }
    assert found == {f[0] for f in BVH_FILES}


@pytest.mark.parametrize(("rel", "frames", "joints", "chans", "ends", "fps"), BVH_FILES, ids=BVH_IDS)
def test_every_shared_bvh_loads(rel: str, frames: int, joints: int, chans: int, ends: int, fps: float) -> None:
    path = data_path(rel)
    m = read_bvh(path)
    sk = m.skeleton
    assert m.channels.shape == (frames, chans) and m.channels.dtype == np.float64
    assert sk.n_joints == joints and sk.n_channels == chans and len(sk.end_sites) == ends
    assert m.frame_rate == fps
    assert m.name == path.stem and m.source_format == "bvh"
    assert m.metadata["file_bytes"] == path.stat().st_size
    assert np.isfinite(m.channels).all()
    assert sk.parents[0] == -1 and (sk.parents[1:] >= 0).all()
    assert all(len(o) == sum(c.endswith("rotation") for c in chs) for o, chs in zip(sk.rotation_order,
                                                                                      sk.channels, strict=True))
    assert sk.has_identity_axes() and sk.angle_unit == "deg"
    assert m.raw_bytes == frames * chans * 4


def test_cmu_layout_and_first_values() -> None:
    """09_06: cgspeed layout, CMU unit and the first numbers of the file, read exactly."""
    m = read_bvh(data_path("cmu/bvh/09_06.bvh"))
    sk = m.skeleton
    assert sk.names[:3] == ["Hips", "LHipJoint", "LeftUpLeg"]
    assert sk.channels[0] == ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
    assert sk.channels[1] == ("Zrotation", "Yrotation", "Xrotation") and sk.rotation_order[1] == "ZYX"
    assert sk.unit_cm == pytest.approx(CMU_UNIT_CM) and CMU_UNIT_CM == pytest.approx(5.6444, abs=1e-4)
    lines = data_path("cmu/bvh/09_06.bvh").read_text().splitlines()
    first = lines[[ln.strip() for ln in lines].index("MOTION") + 3].split()
    assert m.channels[0].tolist() == [float(t) for t in first]
    assert m.metadata["frame_time"] == 0.0083333


def test_units_are_guessed() -> None:
    assert read_bvh(data_path("other/bvh/games105/idle.bvh")).skeleton.unit_cm == 100.0  # metres


def test_crlf_and_tabs_read_the_same(tmp_path: Path) -> None:
    src = data_path("cmu/bvh/09_06.bvh").read_text()
    text = src.replace("\n", "\r\n").replace(" ", "\t").replace("Frame\tTime", "Frame Time")
    crlf = _write(tmp_path, text, "crlf.bvh")
    a, b = read_bvh(data_path("cmu/bvh/09_06.bvh")), read_bvh(crlf)
    assert np.array_equal(a.channels, b.channels) and np.array_equal(a.skeleton.offsets, b.skeleton.offsets)
    assert a.skeleton.names == b.skeleton.names


def test_zero_frames(tmp_path: Path) -> None:
    text = "\n".join(TINY_LINES[:16]) + "\nFrames: 0\nFrame Time: 0.1\n"
    m = read_bvh(_write(tmp_path, text, "zero.bvh"))
    assert m.channels.shape == (0, 9)
    write_bvh(m, tmp_path / "zero_out.bvh")
    assert read_bvh(tmp_path / "zero_out.bvh").channels.shape == (0, 9)


# ------------------------------------------------------------------------------------------- writing
@pytest.mark.parametrize("rel", [f[0] for f in BVH_FILES], ids=BVH_IDS)
def test_write_read_round_trip(rel: str, tmp_path: Path) -> None:
    """Writing a BVH and reading it back gives identical channels, offsets, hierarchy and frame time."""
    m = read_bvh(data_path(rel))
    out = tmp_path / "out.bvh"
    write_bvh(m, out)
    r = read_bvh(out)
    a, b = m.skeleton, r.skeleton
    assert np.array_equal(r.channels, m.channels)
    assert np.array_equal(b.offsets, a.offsets)
    assert b.names == a.names and np.array_equal(b.parents, a.parents)
    assert b.channels == a.channels and b.rotation_order == a.rotation_order
    assert [(j, n) for j, _, n in b.end_sites] == [(j, n) for j, _, n in a.end_sites]
    assert all(np.array_equal(x[1], y[1]) for x, y in zip(a.end_sites, b.end_sites, strict=True))
    assert r.metadata["frame_time"] == m.metadata["frame_time"] and r.frame_rate == m.frame_rate
    if m.decimals is not None:
        assert np.array_equal(r.decimals, m.decimals)


def test_write_is_stable(tmp_path: Path) -> None:
    """A written file written again is byte-identical."""
    m = read_bvh(data_path("cmu/bvh/09_06.bvh"))
    write_bvh(m, tmp_path / "a.bvh")
    write_bvh(read_bvh(tmp_path / "a.bvh"), tmp_path / "b.bvh")
    assert (tmp_path / "a.bvh").read_bytes() == (tmp_path / "b.bvh").read_bytes()


def test_write_refuses_to_overwrite(tmp_path: Path) -> None:
    m = read_bvh(data_path("cmu/bvh/09_06.bvh")).slice(0, 5)
    out = tmp_path / "out.bvh"
    out.write_text("keep me")
    with pytest.raises(MocapzError, match="exists"):
        write_bvh(m, out)
    assert out.read_text() == "keep me"
    write_bvh(m, out, force=True)
    assert np.array_equal(read_bvh(out).channels, m.channels)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bvh"]


def test_write_refuses_non_finite_and_leaves_nothing(tmp_path: Path) -> None:
    m = read_bvh(data_path("cmu/bvh/09_06.bvh")).slice(0, 5)
    ch = m.channels.copy()
    ch[2, 7] = np.nan
    with pytest.raises(FormatError, match="non-finite"):
        write_bvh(m.with_channels(ch), tmp_path / "nan.bvh")
    assert list(tmp_path.iterdir()) == []


def test_write_refuses_asf_axes(tmp_path: Path) -> None:
    sk = read_bvh(data_path("cmu/bvh/09_06.bvh")).skeleton.copy()
    assert sk.axis is not None
    sk.axis[3] = Rotation.from_euler("X", 30, degrees=True).as_matrix()
    m = Motion(sk, np.zeros((2, sk.n_channels)), 120.0)
    with pytest.raises(FormatError, match="axis"):
        write_bvh(m, tmp_path / "axes.bvh")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------- forward kinematics
@pytest.mark.parametrize(
    "rel",
    [
        "cmu/bvh/09_06.bvh",  # ZYX, root with 6 channels
        "other/bvh/bandai_namco/dataset-1_walk_normal_001.bvh",  # ZXY, position channels on every joint
        "other/bvh/games105/walk_and_turn_left.bvh",  # XYZ
        "other/bvh/bvh-python/test_mocapbank.bvh",  # ZXY, 19 joints
        "cmu/bvh_iclone_ccrig/002_03.bvh",  # 101 joints, 41 end sites
    ],
)
def test_fk_matches_per_frame_reference(rel: str) -> None:
    m = read_bvh(data_path(rel))
    sk = m.skeleton
    frames = [0, 1, m.n_frames // 2, m.n_frames - 1]
    pos, rot = forward_kinematics(sk, m.channels[frames])
    assert pos.shape == (len(frames), sk.n_joints + len(sk.end_sites), 3)
    assert rot.shape == (len(frames), sk.n_joints, 3, 3)
    scale = float(np.abs(pos).max())
    for k, f in enumerate(frames):
        ref = _reference_fk(sk, m.channels[f])
        assert np.allclose(pos[k], ref, rtol=0, atol=1e-9 * max(scale, 1.0)), f"frame {f}"


def test_fk_shape_and_motion_positions() -> None:
    m = read_bvh(data_path("cmu/bvh/09_06.bvh"))
    pos = m.positions()
    assert pos.shape == (142, 31 + 7, 3)
    assert np.array_equal(pos, forward_kinematics(m.skeleton, m.channels)[0])
    # the root joint sits at its position channels
    assert np.array_equal(pos[:, 0], m.channels[:, :3])
    # rigid skeleton: every bone keeps its rest length in every frame
    sk = m.skeleton
    par = sk.point_parents
    rest = np.linalg.norm(np.concatenate([sk.offsets, np.array([o for _, o, _ in sk.end_sites])]), axis=1)
    lengths = np.linalg.norm(pos[:, 1:] - pos[:, par[1:]], axis=-1)
    assert np.allclose(lengths, rest[1:][None], rtol=0, atol=1e-9)


def test_fk_tiny_by_hand(tmp_path: Path) -> None:
    """Hand-computed positions: frame 0 turns the chest 90 degrees about Z (end site (0,5,0) -> (-5,0,0))."""
    m = read_bvh(_write(tmp_path, TINY_BVH, "tiny.bvh"))
    pos = m.positions()
    assert np.allclose(pos[0], [[1, 2, 3], [1, 12, 3], [-4, 12, 3]], rtol=0, atol=1e-12)
    # frame 1: R = Rz Rx Ry of the listed channels (Zrotation Xrotation Yrotation)
    def elem(axis: str, deg: float) -> np.ndarray:
        """Elementary rotation matrix about one axis."""
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        return {"X": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]), "Y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
                "Z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]

    r_root = elem("Z", 10) @ elem("X", 20) @ elem("Y", 30)
    r_chest = elem("Z", -45) @ elem("X", 15.5) @ elem("Y", 7.25)
    root = np.array([0.5, 0.25, -1.0])
    chest = root + r_root @ np.array([0, 10, 0])
    end = chest + r_root @ r_chest @ np.array([0, 5, 0])
    assert np.allclose(pos[1], [root, chest, end], rtol=0, atol=1e-12)
    # and scipy's upper-case (intrinsic) Euler convention is that same product
    assert np.allclose(Rotation.from_euler("ZXY", [10, 20, 30], degrees=True).as_matrix(), r_root, atol=1e-15)


def test_position_channels_replace_offset(tmp_path: Path) -> None:
    """A joint with position channels sits at them, not at its OFFSET (Blender / three.js convention)."""
    text = TINY_BVH.replace("CHANNELS 3 Zrotation", "CHANNELS 4 Yposition Zrotation")
    text = text.replace("90.0 0.0 0.0\n", "7.0 90.0 0.0 0.0\n").replace("-45.0 15.5 7.25", "7.0 -45.0 15.5 7.25")
    m = read_bvh(_write(tmp_path, text, "pos.bvh"))
    assert m.channels.shape == (2, 10)
    pos = m.positions()
    assert np.allclose(pos[0], [[1, 2, 3], [1, 9, 3], [-4, 9, 3]], rtol=0, atol=1e-12)


# ------------------------------------------------------------------------------------------- bad input
def _raises(path: Path, match: str, line: int | None = None) -> FormatError:
    """Assert that reading ``path`` raises a FormatError naming the file (and the line, if given)."""
    with pytest.raises(FormatError, match=match) as err:
        read_bvh(path)
    assert str(path) in str(err.value)
    if line is not None:
        assert err.value.line == line
    return err.value


def _tiny(tmp_path: Path, edit: dict[int, str | None] | None = None, name: str = "bad.bvh") -> Path:
    """TINY_BVH with lines replaced (0-based index -> new text, None deletes the line)."""
    lines: list[str | None] = list(TINY_LINES)
    for i, new in (edit or {}).items():
        lines[i] = new
    return _write(tmp_path, "\n".join(x for x in lines if x is not None) + "\n", name)


def test_tiny_reads(tmp_path: Path) -> None:
    m = read_bvh(_tiny(tmp_path))
    assert m.channels.shape == (2, 9) and m.frame_rate == 10.0
    assert m.channels[1].tolist() == [0.5, 0.25, -1.0, 10.0, 20.0, 30.0, -45.0, 15.5, 7.25]
    assert m.decimals is not None and m.decimals.tolist() == [1, 2, 0, 0, 0, 0, 0, 1, 2]


def test_empty_file(tmp_path: Path) -> None:
    _raises(_write(tmp_path, ""), "empty")


def test_binary_file(tmp_path: Path) -> None:
    p = tmp_path / "bin.bvh"
    p.write_bytes(b"HIERARCHY\n\x00\x01\x02")
    _raises(p, "binary")


def test_not_a_bvh(tmp_path: Path) -> None:
    _raises(_write(tmp_path, "hello\nworld\n"), "HIERARCHY", line=1)


def test_no_motion_section(tmp_path: Path) -> None:
    _raises(_write(tmp_path, "\n".join(TINY_LINES[:15]) + "\n"), "MOTION")


def test_truncated_in_hierarchy(tmp_path: Path) -> None:
    _raises(_write(tmp_path, "\n".join(TINY_LINES[:8]) + "\nMOTION\nFrames: 0\nFrame Time: 0.1\n"), "HIERARCHY")


def test_truncated_in_motion(tmp_path: Path) -> None:
    """Cut in the middle of the MOTION rows: the header promises more frames than there are."""
    src = data_path("cmu/bvh/09_06.bvh").read_text()
    cut = _write(tmp_path, src[: len(src) // 2])
    _raises(cut, "truncated")


def test_missing_frame_time(tmp_path: Path) -> None:
    _raises(_tiny(tmp_path, {17: None, 18: None, 19: None}), "Frame Time")


@pytest.mark.parametrize(("line", "text", "match"), [
    (16, "Frames: two", "bad frame count"),
    (16, "Frames: -1", "negative frame count"),
    (17, "Frame Time: 0", "frame time must be positive"),
    (17, "Frame Time: nan", "frame time must be positive"),
    (16, "Frames: 3", "truncated"),
    (16, "Frames: 1", "header says 1 frames"),
])
def test_bad_motion_header(tmp_path: Path, line: int, text: str, match: str) -> None:
    _raises(_tiny(tmp_path, {line: text}), match)


def test_wrong_channel_count_in_a_row(tmp_path: Path) -> None:
    _raises(_tiny(tmp_path, {19: TINY_LINES[19] + " 1.0"}), "frame 2 has 10 values", line=FIRST_ROW_LINE + 1)


def test_short_row(tmp_path: Path) -> None:
    _raises(_tiny(tmp_path, {18: "1.0 2.0 3.0"}), "frame 1 has 3 values", line=FIRST_ROW_LINE)


def test_every_row_one_value_too_many(tmp_path: Path) -> None:
    """Rows of one length that numpy's parser reads whole, but not the hierarchy's: the first row is named."""
    _raises(_tiny(tmp_path, {18: TINY_LINES[18] + " 1.0", 19: TINY_LINES[19] + " 2.0"}), "frame 1 has 10 values",
            line=FIRST_ROW_LINE)


def test_numbers_only_python_reads(tmp_path: Path) -> None:
    """``1_000`` (Python's float reads it, numpy's text parser does not): the values of Python's reading."""
    m = read_bvh(_tiny(tmp_path, {18: TINY_LINES[18].replace("90.0", "1_000.5")}, name="ok.bvh"))
    assert m.channels[0, 6] == 1000.5 and m.channels.shape == (2, 9)
    assert np.array_equal(m.channels[1], [float(t) for t in TINY_LINES[19].split()])


def test_nan_in_a_row(tmp_path: Path) -> None:
    _raises(_tiny(tmp_path, {19: TINY_LINES[19].replace("10.0", "nan")}), "NaN", line=FIRST_ROW_LINE + 1)


def test_inf_in_a_row(tmp_path: Path) -> None:
    _raises(_tiny(tmp_path, {18: TINY_LINES[18].replace("90.0", "-inf")}), "non-finite", line=FIRST_ROW_LINE)


def test_non_numeric_value(tmp_path: Path) -> None:
    _raises(_tiny(tmp_path, {19: TINY_LINES[19].replace("20.0", "abc")}), "non-numeric", line=FIRST_ROW_LINE + 1)


@pytest.mark.parametrize(("line", "text", "match"), [
    (4, "\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Wrotation", "unknown channel"),
    (4, "\tCHANNELS 7 Xposition Yposition Zposition Zrotation Xrotation Yrotation Yrotation", "out of range"),
    (4, "\tCHANNELS six Xposition", "bad channel count"),
    (4, "\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Xrotation", "repeated"),
    (3, "\tOFFSET 0 zero 0", "bad number"),
    (6, "\t[", "expected '{'"),
    (1, "JOINT Hips", "expected ROOT"),
    (5, "\tJOINT Hips", "duplicate joint name"),
])
def test_bad_hierarchy(tmp_path: Path, line: int, text: str, match: str) -> None:
    _raises(_tiny(tmp_path, {line: text}), match, line=line + 1)


def test_two_roots(tmp_path: Path) -> None:
    extra = "ROOT Other\n{\n\tOFFSET 0 0 0\n}"
    _raises(_tiny(tmp_path, {14: "}\n" + extra}), "only one ROOT")


def test_missing_file(tmp_path: Path) -> None:
    _raises(tmp_path / "nope.bvh", "no such file")


def test_unit_guess_ignores_a_locomotion_root_far_from_the_body() -> None:
    """Bandai-Namco's dataset-2 rig puts the hips 427 units from a floor root: the body is still 184 cm tall,
    the same unit as its dataset-1 sibling (the rest height counts the subtree of the first branching joint)."""
    far = read_bvh(data_path("other/bvh/bandai_namco/dataset-2_walk_elderly_004.bvh")).skeleton
    near = read_bvh(data_path("other/bvh/bandai_namco/dataset-1_walk_normal_001.bvh")).skeleton
    assert far.unit_cm == near.unit_cm == 1.0
    assert "184" in far.unit_note


def _decimals_whole(values: np.ndarray, max_decimals: int = 9) -> np.ndarray | None:
    """common_decimals on the whole matrix at once (its code before it went a few thousand rows at a time)."""
    from mocapz.io.common import exception_budget, fits_decimals

    rows, cols = values.shape
    budget, slack = exception_budget(rows), rows // 100
    finite = np.isfinite(values)
    fit = np.stack([fits_decimals(values, np.full(cols, d)) for d in range(max_decimals + 1)])
    never = finite & ~fit.any(axis=0)
    if (never.sum(axis=0) > budget).any():
        return None
    ok = ((finite & ~never)[None] & ~fit).sum(axis=1) <= slack
    if not ok.any(axis=0).all():
        return None
    return np.argmax(ok, axis=0).astype(np.int64)


def test_common_decimals_of_a_long_clip_in_steps() -> None:
    """A clip of several :data:`~mocapz.io.common.DECIMAL_ROWS` steps: the decimals (and the None) of the whole
    matrix at once, with off-decimal values spread over the steps up to each budget and past it."""
    from mocapz.io import common

    base = read_bvh(data_path("cmu/bvh/06_13.bvh")).channels
    values = np.concatenate([base, base[::-1], base])[: 3 * common.DECIMAL_ROWS + 7]
    rows = values.shape[0]
    rng = np.random.default_rng(4)
    budget, slack = common.exception_budget(rows), rows // 100
    cases = [values]
    for col, extra in ((3, slack), (5, slack + 1), (7, budget), (8, budget + 1)):
        v = values.copy()
        at = rng.choice(rows, extra, replace=False)
        v[at, col] += 1e-5 if extra <= slack + 1 else np.pi * 1e-7  # a decimal more, or off every count
        cases.append(v)
    for v in cases:
        got, want = common.common_decimals(v), _decimals_whole(v)
        assert (got is None) == (want is None) and (got is None or np.array_equal(got, want))
    assert common.common_decimals(cases[0]) is not None and common.common_decimals(cases[-1]) is None


def _rows_before(values: np.ndarray, decimals: np.ndarray | None, sep: str = " ") -> str:
    """format_rows made whole (its code before it went a few thousand rows a piece)."""
    from mocapz.io.common import exception_budget, fits_decimals

    if decimals is None:
        return "\n".join(sep.join(map(repr, row)) for row in values.tolist()) + "\n"
    dec = np.broadcast_to(np.asarray(decimals, dtype=np.int64), (values.shape[1],))
    fmts = [f"%.{int(d)}f" for d in dec]
    off = ~fits_decimals(values, dec) & np.isfinite(values)
    exact = off & (off.sum(axis=0) <= exception_budget(values.shape[0]))[None, :]
    noise = (np.abs(values) < 0.5 * 10.0 ** (-dec.astype(float))) & ~fits_decimals(values, dec) & ~exact
    lines = [sep.join(fmts) % tuple(row) for row in np.where(noise, 0.0, values).tolist()]
    for r in np.flatnonzero(exact.any(axis=1)).tolist():
        lines[r] = sep.join(repr(v) if e else f % v
                            for f, v, e in zip(fmts, values[r].tolist(), exact[r].tolist(), strict=True))
    return "\n".join(lines) + "\n"


def test_rows_written_in_pieces_are_the_whole_text(tmp_path: Path) -> None:
    """A clip of several :data:`~mocapz.io.common.DECIMAL_ROWS` pieces writes the text made whole: its own
    decimals with a few exact values (-0, float artefacts) across the pieces, a lossy copy, shortest repr."""
    from mocapz.io import common

    m = read_bvh(data_path("cmu/bvh/06_13.bvh"))
    rows = 2 * common.DECIMAL_ROWS + 11
    values = np.concatenate([m.channels, m.channels[::-1]])[:rows].copy()
    rng = np.random.default_rng(2)
    at = rng.choice(rows, 40, replace=False)
    values[at, 7] += 1e-9  # off the column's decimals: exact values, in every piece
    values[at[:5], 8] = -0.0
    noisy = values + rng.normal(0, 1e-3, values.shape)  # a lossy decode: rounded, noise near zero to 0.000
    for v, dec in ((values, m.decimals), (noisy, m.decimals), (values[:300], None), (values[:0], m.decimals)):
        assert common.format_rows(v, dec) == _rows_before(v, dec)
    out = tmp_path / "long.bvh"
    write_bvh(m.with_channels(values, m.decimals), out)
    back = read_bvh(out)
    assert np.array_equal(back.channels, values) and out.read_text().endswith(_rows_before(values, m.decimals))
