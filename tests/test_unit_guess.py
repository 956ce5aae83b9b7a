"""The length-unit guess reads the body's proportions: a shared clip rewritten in metres, millimetres and
inches, and with a locomotion root far below the hips, is guessed right; every shared skeleton gets a
plausible unit; ``--unit`` overrides the guess."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import data_path

from mocapz.cli.main import cli
from mocapz.io import load
from mocapz.io.bvh import read_bvh, write_bvh
from mocapz.io.common import (
    CMU_UNIT_CM,
    HUMAN_HEIGHT_CM,
    SPAN_PER_HEIGHT,
    chain_span,
    guess_unit_cm,
    rest_height,
)
from mocapz.model.motion import Motion

CM_CLIPS = ("other/bvh/bvh-python/test_mocapbank.bvh", "other/bvh/bandai_namco/dataset-1_walk_normal_001.bvh")
UNITS = {"m": 100.0, "cm": 1.0, "mm": 0.1, "in": 2.54}


def _rescaled(m: Motion, cm_per_unit: float) -> Motion:
    """The clip with every length (offsets, end sites, position channels) in another unit."""
    s = m.skeleton.unit_cm / cm_per_unit  # type: ignore[operator]
    sk = m.skeleton.copy()
    sk.offsets = sk.offsets * s
    sk.end_sites = [(j, o * s, n) for j, o, n in sk.end_sites]
    ch = m.channels.copy()
    ch[:, ~sk.rotation_columns()] *= s
    return replace(m, skeleton=sk, channels=ch, decimals=None)


def _with_floor_root(text: str, hips_height: float) -> str:
    """A BVH text with a new root ``Floor`` on the ground, the old root's OFFSET ``hips_height`` above it."""
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("ROOT "))
    m = lines.index("MOTION")
    off = next(k for k in range(i, m) if lines[k].strip().startswith("OFFSET"))
    hierarchy = [*lines[:i], "ROOT Floor", "{", "OFFSET 0 0 0", "CHANNELS 3 Xposition Yposition Zposition",
                 "JOINT " + lines[i].split()[1], *lines[i + 1:off], f"OFFSET 0 {hips_height:.6f} 0",
                 *lines[off + 1:m], "}"]
    rows = ["0 0 0 " + ln for ln in lines[m + 3:] if ln.strip()]
    return "\n".join([*hierarchy, *lines[m:m + 3], *rows]) + "\n"


@pytest.mark.parametrize("clip", CM_CLIPS)
@pytest.mark.parametrize("unit", sorted(UNITS))
def test_rescaled_clip_is_guessed(tmp_path: Path, clip: str, unit: str) -> None:
    m = read_bvh(data_path(clip))
    assert m.skeleton.unit_cm == 1.0
    path = tmp_path / f"{unit}.bvh"
    write_bvh(_rescaled(m, UNITS[unit]), path)
    back = read_bvh(path)
    assert back.skeleton.unit_cm == UNITS[unit], back.skeleton.unit_note
    assert rest_height(back.skeleton) * UNITS[unit] == pytest.approx(rest_height(m.skeleton), rel=1e-4)


@pytest.mark.parametrize("unit", sorted(UNITS))
def test_far_floor_root_does_not_change_the_guess(tmp_path: Path, unit: str) -> None:
    """Hips 427 cm above a floor root (Bandai-Namco dataset-2's rig), in every unit."""
    m = read_bvh(data_path(CM_CLIPS[0]))
    path = tmp_path / f"{unit}.bvh"
    write_bvh(_rescaled(m, UNITS[unit]), path)
    far = tmp_path / f"far_{unit}.bvh"
    far.write_text(_with_floor_root(path.read_text(), 427.0 / UNITS[unit]))
    back = read_bvh(far)
    assert back.skeleton.names[:2] == ["Floor", m.skeleton.names[0]]
    assert back.skeleton.offsets[1, 1] * UNITS[unit] == pytest.approx(427.0, rel=1e-6)
    assert back.skeleton.unit_cm == UNITS[unit], back.skeleton.unit_note
    # the hips' position channels replace their OFFSET (METRICS.md): the body moves as before
    assert np.allclose(back.positions()[:, 1:], read_bvh(path).positions(), atol=1e-9)


def _folded(m: Motion) -> Motion:
    """The clip with a zig-zag rest pose: every bone along x, its direction flipping at each level of the
    tree (bone lengths kept, so the chains are unchanged; the rest pose is no standing one)."""
    sk = m.skeleton.copy()
    depth = np.zeros(sk.n_joints, dtype=np.int64)
    for j in range(1, sk.n_joints):
        depth[j] = depth[sk.parents[j]] + 1
    sign = np.where(depth % 2 == 0, 1.0, -1.0)
    sk.offsets = np.linalg.norm(sk.offsets, axis=1)[:, None] * sign[:, None] * np.array([1.0, 0.0, 0.0])
    sk.end_sites = [(j, -sign[j] * np.linalg.norm(o) * np.array([1.0, 0.0, 0.0]), n) for j, o, n in sk.end_sites]
    return replace(m, skeleton=sk)


@pytest.mark.parametrize(("unit", "expected"), [("cm", None), ("mm", 0.1), ("m", 100.0)])
def test_rest_pose_that_is_not_standing(tmp_path: Path, unit: str, expected: float | None) -> None:
    """A folded rest pose: 59 cm tall. In mm and m that is no human height in any unit and the bone chains
    (1.6 m) decide; in cm it reads as 59 inches while the chains say cm: the guess is unknown, not wrong."""
    m = _folded(_rescaled(read_bvh(data_path(CM_CLIPS[0])), UNITS[unit]))
    path = tmp_path / f"folded_{unit}.bvh"
    write_bvh(m, path)
    back = read_bvh(path)
    span_cm = chain_span(back.skeleton) / SPAN_PER_HEIGHT * UNITS[unit]
    assert 150 < span_cm < 170
    assert back.skeleton.unit_cm == expected, back.skeleton.unit_note
    if expected is None:
        assert "--unit" in back.skeleton.unit_note and np.isnan(rest_height(back.skeleton))


def test_chain_span_ignores_the_rest_pose() -> None:
    m = read_bvh(data_path(CM_CLIPS[0]))
    assert chain_span(_folded(m).skeleton) == pytest.approx(chain_span(m.skeleton), rel=1e-12)
    # toe to fingertip over height, on the shared skeletons: about 1.5
    assert 1.3 < chain_span(m.skeleton) / rest_height(m.skeleton) < 1.7


@pytest.mark.parametrize(("height", "cm"), [
    (1.75, 100.0), (175.0, 1.0), (1750.0, 0.1), (69.0, 2.54), (31.0, CMU_UNIT_CM), (1.25, 100.0), (2.15, 100.0),
    (0.3, None), (100.0, None), (3.0, None), (43.0, None), (500.0, None), (12.0, None), (float("nan"), None),
])
def test_guess_by_height(height: float, cm: float | None) -> None:
    got, note = guess_unit_cm(height)
    assert got == cm, note
    if cm is not None:
        assert HUMAN_HEIGHT_CM[0] <= height * cm <= HUMAN_HEIGHT_CM[1]
    else:
        assert "--unit" in note


SHARED_SKELETONS = (
    "cmu/bvh/01_01.bvh", "cmu/bvh/12_01.bvh", "cmu/bvh_iclone_ccrig/002_03.bvh",
    "other/bvh/bandai_namco/dataset-1_dance-short_normal_001.bvh",
    "other/bvh/bandai_namco/dataset-1_punch_normal_001.bvh",
    "other/bvh/bandai_namco/dataset-1_walk_normal_001.bvh",
    "other/bvh/bandai_namco/dataset-2_walk_elderly_004.bvh",
    "other/bvh/bvh-python/test_mocapbank.bvh", "other/bvh/games105/idle.bvh",
    "other/bvh/games105/walk_and_turn_left.bvh", "other/bvh/pymo/AV_8Walk_Meredith_HVHA_Rep1.bvh",
    "cmu/asfamc/01_01.amc", "cmu/asfamc/11_01.amc", "cmu/asfamc/backflip.amc", "cmu/asfamc/lambada.amc",
    "other/asfamc/amcparser/walking.amc",
)


@pytest.mark.parametrize("rel", SHARED_SKELETONS)
def test_every_shared_skeleton_gets_a_human_height(rel: str) -> None:
    """Every shared skeleton has a unit, and in it the body's median height over the clip (vertical extent
    of its joints and end sites, below the locomotion root) is a human one."""
    m = load(data_path(rel))
    assert isinstance(m, Motion)
    sk = m.skeleton
    assert sk.unit_cm is not None, sk.unit_note
    pos = m.positions()
    body = sk.body_points()
    up = int(np.argmax(np.median(np.ptp(pos[:, body], axis=1), axis=0)))
    height_cm = float(np.median(np.ptp(pos[:, body, up], axis=1))) * sk.unit_cm
    assert 100.0 <= height_cm <= 230.0, (rel, height_cm, sk.unit_note)


def test_unit_flag_overrides_the_guess(tmp_path: Path) -> None:
    src = str(data_path(CM_CLIPS[0]))
    runner = CliRunner()
    for flag, cm in (("m", 100.0), ("in", 2.54), ("cmu", CMU_UNIT_CM)):
        out = runner.invoke(cli, ["eval", src, src, "--json", "--unit", flag], catch_exceptions=False).output
        assert json.loads(out)["unit_cm"] == pytest.approx(cm)
    mcz = tmp_path / "clip.mcz"
    res = runner.invoke(cli, ["compress", src, "-o", str(mcz), "--unit", "mm", "-q"], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    out = runner.invoke(cli, ["info", str(mcz), "--json"], catch_exceptions=False).output
    assert json.loads(out)["unit_cm"] == pytest.approx(0.1)


def test_body_points_leave_out_the_locomotion_root() -> None:
    far = read_bvh(data_path("other/bvh/bandai_namco/dataset-2_walk_elderly_004.bvh")).skeleton
    assert far.names[:2] == ["joint_Root", "Hips"]
    assert far.body_points().tolist() == list(range(1, far.n_points))
    cmu = read_bvh(data_path("cmu/bvh/09_06.bvh")).skeleton
    assert cmu.body_points().tolist() == list(range(cmu.n_points))
