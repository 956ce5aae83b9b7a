"""Acclaim ASF/AMC reader and writer: real CMU and non-CMU files, round trips, BVH cross-check, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import data_path
from scipy.spatial.transform import Rotation

from mocapz.errors import FormatError, MocapzError
from mocapz.io import amc as amc_io
from mocapz.io.amc import read_asfamc, write_asfamc
from mocapz.io.asf import find_asf
from mocapz.io.asf_write import generate_asf
from mocapz.io.bvh import read_bvh
from mocapz.io.common import CMU_UNIT_CM
from mocapz.model.kinematics import forward_kinematics
from mocapz.model.motion import Motion

# (amc, frames, joints, channels) as listed in the data MANIFEST
PAIRS = [
    ("cmu/asfamc/01_01.amc", 2751, 31, 62),
    ("cmu/asfamc/11_01.amc", 597, 31, 62),
    ("cmu/asfamc/lambada.amc", 2180, 31, 62),
    ("cmu/asfamc/backflip.amc", 247, 31, 62),
    ("other/asfamc/amcparser/walking.amc", 1741, 34, 87),
]

# cgspeed BVH joint -> CMU ASF bone (same order in both files)
BVH_TO_ASF = {
    "Hips": "root", "LHipJoint": "lhipjoint", "LeftUpLeg": "lfemur", "LeftLeg": "ltibia",
    "LeftFoot": "lfoot", "LeftToeBase": "ltoes", "RHipJoint": "rhipjoint", "RightUpLeg": "rfemur",
    "RightLeg": "rtibia", "RightFoot": "rfoot", "RightToeBase": "rtoes", "LowerBack": "lowerback",
    "Spine": "upperback", "Spine1": "thorax", "Neck": "lowerneck", "Neck1": "upperneck", "Head": "head",
    "LeftShoulder": "lclavicle", "LeftArm": "lhumerus", "LeftForeArm": "lradius", "LeftHand": "lwrist",
    "LeftFingerBase": "lhand", "LeftHandIndex1": "lfingers", "LThumb": "lthumb",
    "RightShoulder": "rclavicle", "RightArm": "rhumerus", "RightForeArm": "rradius", "RightHand": "rwrist",
    "RightFingerBase": "rhand", "RightHandIndex1": "rfingers", "RThumb": "rthumb",
}


@pytest.fixture(scope="module")
def cmu_0101() -> Motion:
    return read_asfamc(data_path("cmu/asfamc/01_01.amc"))


def _fk(motion: Motion) -> np.ndarray:
    return forward_kinematics(motion.skeleton, motion.channels)[0]


# ------------------------------------------------------------------------------------------- reading
@pytest.mark.parametrize(("rel", "frames", "joints", "chans"), PAIRS)
def test_every_shared_pair_loads(rel: str, frames: int, joints: int, chans: int) -> None:
    amc = data_path(rel)
    m = read_asfamc(amc)
    sk = m.skeleton
    assert m.channels.shape == (frames, chans)
    assert sk.n_joints == joints and sk.names[0] == "root"
    assert m.source_format == "asfamc" and m.frame_rate == 120.0 and m.name == amc.stem
    assert np.isfinite(m.channels).all()
    assert m.raw_bytes == frames * chans * 4
    asf = Path(m.metadata["asf_path"])
    assert m.metadata["path"] == str(amc)
    assert m.metadata["file_bytes"] == amc.stat().st_size + asf.stat().st_size
    assert sk.angle_unit == "deg"
    assert len(sk.end_sites) == sum(1 for j in range(joints) if j and not sk.children(j))
    assert _fk(m).shape == (frames, sk.n_points, 3)


def test_cmu_layout_and_units(cmu_0101: Motion) -> None:
    sk = cmu_0101.skeleton
    assert sk.channels[0] == ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
    assert sk.rotation_order[0] == "ZYX"  # dof rx ry rz: applied x first, M = Rz Ry Rx
    lfoot = sk.index("lfoot")
    assert sk.channels[lfoot] == ("Xrotation", "Zrotation") and sk.rotation_order[lfoot] == "ZX"
    assert sk.channels[sk.index("lhipjoint")] == ()  # no dofs, not in the AMC
    assert sk.unit_cm == pytest.approx(CMU_UNIT_CM) and "0.45" in sk.unit_note
    # joint = bone base: lfemur sits at the tip of lhipjoint (direction * length from 01.asf)
    assert np.allclose(sk.offsets[sk.index("lfemur")], np.array([0.566809, -0.746272, 0.349008]) * 2.40479)
    assert np.allclose(sk.axis[sk.index("lfemur")], Rotation.from_euler("z", 20, degrees=True).as_matrix())
    # first AMC record: root 9.37216 17.8693 -17.3198 -2.01677 -7.59696 -3.23164
    assert cmu_0101.channels[0, :6].tolist() == [9.37216, 17.8693, -17.3198, -2.01677, -7.59696, -3.23164]


def test_non_cmu_skeleton_units() -> None:
    m = read_asfamc(data_path("other/asfamc/amcparser/walking.amc"))
    sk = m.skeleton
    assert "LeftToesJoint" in sk.names and sk.n_joints == 34
    # ":units length 0.01" read the CMU way would make a 4.75 m skeleton; the data is in metres
    assert sk.unit_cm == 100.0 and "metres" in sk.unit_note
    height = np.ptp(_fk(m)[:, :, 1], axis=1).max()
    assert 1.5 < height < 2.0


def test_frame_rate_keyword() -> None:
    m = read_asfamc(data_path("cmu/asfamc/backflip.amc"), frame_rate=60)
    assert m.frame_rate == 60.0 and m.duration == pytest.approx(247 / 60)


def test_rotation_convention_small_skeleton(tmp_path: Path) -> None:
    """Hand-made ASF: local rotation = C @ Rz @ Rx @ C.T for ``dof rx rz`` and ``axis 0 0 90 XYZ``."""
    asf = tmp_path / "arm.asf"
    asf.write_text(
        ":version 1.10\n:name t\n:units\n  length 1\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n"
        "  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n:bonedata\n  begin\n    id 1\n    name a\n"
        "    direction 1 0 0\n    length 2\n    axis 0 0 90 XYZ\n    dof rx rz\n    limits (-inf inf)\n"
        "           (-inf inf)\n  end\n:hierarchy\n  begin\n    root a\n  end\n"
    )
    amc = tmp_path / "arm.amc"
    amc.write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 1 2 3 0 0 0\na 30 40\n")
    m = read_asfamc(amc)
    c = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    rz, rx = (Rotation.from_euler(a, v, degrees=True).as_matrix() for a, v in (("z", 40), ("x", 30)))
    tip = np.array([1, 2, 3]) + c @ rz @ rx @ c.T @ np.array([2.0, 0, 0])
    assert np.allclose(_fk(m)[0, -1], tip)


# ------------------------------------------------------------------------------------------- round trips
@pytest.mark.parametrize("rel", [p[0] for p in PAIRS])
def test_write_read_round_trip(rel: str, tmp_path: Path) -> None:
    m = read_asfamc(data_path(rel))
    out = write_asfamc(m, tmp_path / "copy.amc")
    assert out == [tmp_path / "copy.amc", tmp_path / "copy.asf"]
    assert out[1].read_bytes() == Path(m.metadata["asf_path"]).read_bytes()  # skeleton kept verbatim
    r = read_asfamc(out[0])
    assert r.skeleton.names == m.skeleton.names and r.skeleton.channels == m.skeleton.channels
    assert np.array_equal(r.channels, m.channels)
    assert np.array_equal(_fk(r), _fk(m))
    # writing the read-back motion again gives the same bytes
    again = write_asfamc(r, tmp_path / "again.amc")
    assert again[0].read_bytes() == out[0].read_bytes().replace(b"copy.asf", b"again.asf")


@pytest.mark.parametrize("rel", ["cmu/asfamc/11_01.amc", "other/asfamc/amcparser/walking.amc"])
def test_generated_asf_is_exact(rel: str, tmp_path: Path) -> None:
    """Without the original ASF text the skeleton is regenerated (axes included) with identical FK."""
    m = read_asfamc(data_path(rel))
    m.skeleton = m.skeleton.copy()
    m.skeleton.extra = {}
    r = read_asfamc(write_asfamc(m, tmp_path / "gen.amc")[0])
    assert r.skeleton.names == m.skeleton.names and r.skeleton.channels == m.skeleton.channels
    assert np.array_equal(r.channels, m.channels)
    assert np.allclose(_fk(r), _fk(m), rtol=0, atol=1e-9)
    assert r.skeleton.unit_cm == pytest.approx(m.skeleton.unit_cm)


def _point_index(src: Motion, back: Motion) -> np.ndarray:
    """Index in ``back`` of every FK point of ``src`` (the BVH root is the ASF ``root``)."""
    root = src.skeleton.names[0]
    names = back.skeleton.point_names
    return np.array([names.index("root" if n == root else n) for n in src.skeleton.point_names])


@pytest.mark.parametrize(
    "rel",
    [
        "cmu/bvh/01_01.bvh",
        "other/bvh/bandai_namco/dataset-1_walk_normal_001.bvh",  # 6 channels on every joint
        "other/bvh/games105/idle.bvh",  # multi-child joints at different offsets
        "other/bvh/pymo/AV_8Walk_Meredith_HVHA_Rep1.bvh",
        "cmu/bvh_iclone_ccrig/002_03.bvh",
    ],
)
def test_bvh_to_asfamc_is_exact(rel: str, tmp_path: Path) -> None:
    m = read_bvh(data_path(rel)).slice(0, 200)
    r = read_asfamc(write_asfamc(m, tmp_path / "conv.amc")[0])
    root = m.skeleton.names[0]
    labels = r.skeleton.channel_labels()
    cols = [labels.index(("root" if lab.split(".")[0] == root else lab.split(".")[0]) + "." + lab.split(".")[1])
            for lab in m.skeleton.channel_labels()]
    assert np.array_equal(r.channels[:, cols], m.channels)
    assert np.allclose(_fk(r)[:, _point_index(m, r)], _fk(m), rtol=0, atol=1e-9)


def test_generate_asf_cmu_bvh_needs_no_extra_bones() -> None:
    sk = read_bvh(data_path("cmu/bvh/09_06.bvh")).skeleton
    text, joint_of_bone = generate_asf(sk)
    assert "_dum" not in text and len(joint_of_bone) == 31


# ------------------------------------------------------------------------------------------- cross-format
def test_cross_format_fk_matches_cgspeed_bvh(cmu_0101: Motion) -> None:
    """CMU 01_01 as AMC and as cgspeed BVH (frame 0 = added T-pose) give the same motion.

    The cgspeed skeleton puts a BVH joint at the base of the ASF bone of the same rank, except that it
    drops the length of ``thorax`` (Neck/LeftShoulder/RightShoulder sit at Spine1) and of ``l/rwrist``
    (FingerBase/Thumb sit at the Hand). So: (1) points whose chain is identical are compared directly,
    (2) every global joint rotation is compared, (3) all 38 points are compared after FK of the BVH
    channels on the ASF geometry. Measured: 1e-4 units, 3.3e-4 degrees, 8.9e-5 units.
    """
    a = cmu_0101
    b = read_bvh(data_path("cmu/bvh/01_01.bvh")).slice(1)
    assert [BVH_TO_ASF[n] for n in b.skeleton.names] == a.skeleton.names
    pa, ra = forward_kinematics(a.skeleton, a.channels)
    pb, rb = forward_kinematics(b.skeleton, b.channels)
    assert np.abs(pa[:, 0] - pb[:, 0]).max() < 5.1e-5  # root: the same numbers, BVH rounded to 4 decimals
    same = {"Hips": "root", "LeftUpLeg": "lfemur", "LeftLeg": "ltibia", "LeftFoot": "lfoot",
            "LeftToeBase": "ltoes", "RightUpLeg": "rfemur", "RightLeg": "rtibia", "RightFoot": "rfoot",
            "RightToeBase": "rtoes", "Spine": "upperback", "Spine1": "thorax", "Neck": "thorax",
            "LeftShoulder": "thorax", "LeftToeBase_End": "ltoes_End", "RightToeBase_End": "rtoes_End"}
    ib = [b.skeleton.point_names.index(n) for n in same]
    ia = [a.skeleton.point_names.index(n) for n in same.values()]
    assert np.abs(pa[:, ia] - pb[:, ib]).max() < 0.01
    cos = (np.einsum("fjab,fjab->fj", ra, rb) - 1) / 2
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 0.01
    on_asf = b.skeleton.copy()
    on_asf.offsets = a.skeleton.offsets.copy()
    on_asf.end_sites = a.skeleton.end_sites
    assert np.abs(forward_kinematics(on_asf, b.channels)[0] - pa).max() < 0.01


# ------------------------------------------------------------------------------------------- bad input
def _amc_head(frames: int) -> list[str]:
    """Header and the first ``frames`` records of CMU 01_01.amc (30 lines per record)."""
    lines = data_path("cmu/asfamc/01_01.amc").read_text().splitlines()
    return lines[: 4 + 30 * frames]


def _pair(tmp_path: Path, amc_lines: list[str], name: str = "01_01.amc") -> Path:
    (tmp_path / "01.asf").write_bytes(data_path("cmu/asfamc/01.asf").read_bytes())
    amc = tmp_path / name
    amc.write_text("\n".join(amc_lines) + "\n")
    return amc


def _raises(amc: Path, match: str, line: int | None = None, **kw: object) -> FormatError:
    with pytest.raises(FormatError, match=match) as err:
        read_asfamc(amc, **kw)  # type: ignore[arg-type]
    assert str(amc) in str(err.value)
    if line is not None:
        assert err.value.line == line
    return err.value


def test_small_copy_reads(tmp_path: Path) -> None:
    m = read_asfamc(_pair(tmp_path, _amc_head(3)))
    assert m.n_frames == 3 and m.metadata["asf_path"].endswith("01.asf")


def test_empty_amc(tmp_path: Path) -> None:
    _raises(_pair(tmp_path, [""]), "empty")


def test_empty_asf(tmp_path: Path) -> None:
    amc = _pair(tmp_path, _amc_head(2))
    (tmp_path / "01.asf").write_text("")
    with pytest.raises(FormatError, match="empty") as err:
        read_asfamc(amc)
    assert str(tmp_path / "01.asf") in str(err.value)


def test_amc_bone_not_in_asf(tmp_path: Path) -> None:
    lines = _amc_head(2)
    lines[10] = "tail 1 2 3"
    _raises(_pair(tmp_path, lines), "'tail' is not in the ASF", line=11)


def test_truncated_last_frame(tmp_path: Path) -> None:
    _raises(_pair(tmp_path, _amc_head(3)[:-5]), "frame 3 is incomplete")


def test_truncated_last_line(tmp_path: Path) -> None:
    lines = _amc_head(2)
    lines[-1] = lines[-1].split()[0]  # "ltoes" without its value
    _raises(_pair(tmp_path, lines), "has 0 values", line=len(lines))


def test_non_numeric_value(tmp_path: Path) -> None:
    lines = _amc_head(3)
    lines[40] = lines[40].split()[0] + " 1.5 abc 2"
    _raises(_pair(tmp_path, lines), "non-numeric value 'abc'", line=41)


def test_nan_value(tmp_path: Path) -> None:
    lines = _amc_head(3)
    lines[40] = lines[40].split()[0] + " 1.5 nan 2"
    _raises(_pair(tmp_path, lines), "NaN", line=35)  # the record of frame 2 starts at line 35


def test_wrong_value_count(tmp_path: Path) -> None:
    lines = _amc_head(2)
    lines[5] += " 7"  # root with 7 values
    _raises(_pair(tmp_path, lines), "has 7 values", line=6)


def test_different_bone_set(tmp_path: Path) -> None:
    lines = _amc_head(3)
    del lines[40]  # one bone line of frame 2 missing
    _raises(_pair(tmp_path, lines), "frame 2 is incomplete")


def test_frame_numbers_must_be_consecutive(tmp_path: Path) -> None:
    lines = _amc_head(3)
    lines[34] = "7"
    _raises(_pair(tmp_path, lines), "frame number 7 follows 1", line=35)


def test_missing_asf(tmp_path: Path) -> None:
    amc = tmp_path / "walk.amc"
    amc.write_text("\n".join(_amc_head(2)) + "\n")
    _raises(amc, "cannot tell which skeleton")
    with pytest.raises(FormatError, match="no such file") as err:
        read_asfamc(amc, tmp_path / "nope.asf")
    assert "nope.asf" in str(err.value)


def test_find_asf_rules(tmp_path: Path) -> None:
    for name in ("1.asf", "11.asf", "11_01.amc"):
        (tmp_path / name).write_text("x")
    assert find_asf(tmp_path / "11_01.amc") == tmp_path / "11.asf"  # 1.asf is not followed by "_"
    (tmp_path / "11_01.asf").write_text("x")
    assert find_asf(tmp_path / "11_01.amc") == tmp_path / "11_01.asf"
    (tmp_path / "1_0.asf").write_text("x")
    (tmp_path / "1_02.amc").write_text("x")
    assert find_asf(tmp_path / "1_02.amc") == tmp_path / "1.asf"  # 1_0 is followed by "2"
    (tmp_path / "1_0_2.amc").write_text("x")
    with pytest.raises(FormatError, match="1_0_2.amc"):
        find_asf(tmp_path / "1_0_2.amc")  # 1.asf and 1_0.asf both start it


def test_bad_asf_hierarchy(tmp_path: Path) -> None:
    amc = _pair(tmp_path, _amc_head(2))
    asf = tmp_path / "01.asf"
    asf.write_text(asf.read_text().replace("lhipjoint lfemur", "lhipjoint lfemurx"))
    with pytest.raises(FormatError, match="lfemurx") as err:
        read_asfamc(amc)
    assert str(asf) in str(err.value) and err.value.line is not None


# ------------------------------------------------------------------------------------------- writing
def test_write_refuses_to_overwrite(tmp_path: Path, cmu_0101: Motion) -> None:
    m = cmu_0101.slice(0, 10)
    amc, asf = write_asfamc(m, tmp_path / "w.amc")
    before = amc.read_bytes()
    with pytest.raises(MocapzError, match="exists"):
        write_asfamc(m.slice(0, 5), amc)
    assert amc.read_bytes() == before
    amc.unlink()
    write_asfamc(m, amc)  # identical ASF already there: fine
    asf.write_text("something else")
    amc.unlink()
    with pytest.raises(MocapzError, match="different skeleton"):
        write_asfamc(m, amc)
    assert not amc.exists()
    write_asfamc(m, amc, force=True)
    assert np.array_equal(read_asfamc(amc).channels, m.channels)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.amc", "w.asf"]


def test_failed_write_leaves_nothing(tmp_path: Path, cmu_0101: Motion, monkeypatch: pytest.MonkeyPatch) -> None:
    bad = cmu_0101.slice(0, 5)
    bad.channels[2, 3] = np.nan
    with pytest.raises(FormatError, match="non-finite"):
        write_asfamc(bad, tmp_path / "bad.amc")
    assert list(tmp_path.iterdir()) == []

    real = amc_io.atomic_write

    def failing(path, write, force=False):  # type: ignore[no-untyped-def]
        if Path(path).suffix == ".amc":
            def boom(tmp: Path) -> None:
                tmp.write_text("partial")
                raise OSError("disk full")
            return real(path, boom, force)
        return real(path, write, force)

    monkeypatch.setattr(amc_io, "atomic_write", failing)
    with pytest.raises(OSError, match="disk full"):
        write_asfamc(cmu_0101.slice(0, 5), tmp_path / "f.amc")
    assert list(tmp_path.iterdir()) == []
