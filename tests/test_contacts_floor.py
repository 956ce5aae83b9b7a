"""The floor under a foot is local: a foot is planted within 5 cm of its lowest height over the last
``FLOOR_WINDOW_S`` seconds, so one deep sample, a foot through the floor or a step up does not take the
clip's other contacts away, and a stream that keeps a few seconds of history finds the whole file's contacts."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

from mocapz.io import load
from mocapz.metrics.contacts import FLOOR_WINDOW_S, find_contacts, floor_heights
from mocapz.model.motion import Motion


def _clip(name: str, frames: int | None = None) -> tuple[Motion, np.ndarray, np.ndarray]:
    m = load(data_path(f"cmu/bvh/{name}.bvh"))
    assert isinstance(m, Motion)
    if frames is not None:
        m = m.slice(0, frames)
    a = m.positions()
    return m, a, np.ones(a.shape[:2], dtype=bool)


def test_floor_is_the_trailing_minimum() -> None:
    rng = np.random.default_rng(3)
    for n in (1, 2, 7, 300):
        for back in (0, 1, 2, 5, 240, 1000):
            h = rng.normal(size=n)
            h[rng.random(n) < 0.1] = np.inf  # missing samples
            ref = np.array([h[max(0, t - back):t + 1].min() for t in range(n)])
            assert np.array_equal(floor_heights(h, back), ref), (n, back)


def test_a_deep_glitch_takes_away_no_contact_before_it_or_long_after() -> None:
    m, a, valid = _clip("02_05")
    con = find_contacts(m, a, valid, m.skeleton.unit_cm)
    back = int(round(FLOOR_WINDOW_S * m.frame_rate))
    g = a.shape[0] // 3
    i = 0
    glitch = a.copy()
    glitch[g, con.feet[i], con.up] -= 50.0 / m.skeleton.unit_cm  # one sample half a metre under the floor
    after = find_contacts(m, glitch, valid, m.skeleton.unit_cm)
    assert np.array_equal(after.feet, con.feet)
    assert np.array_equal(after.steps[:g - 1], con.steps[:g - 1])
    assert np.array_equal(after.steps[g + back + 1:], con.steps[g + back + 1:])
    assert con.steps[g + back + 1:, i].any()  # the test means something: contacts after the glitch's window


def test_a_floor_stepping_up_keeps_the_contacts_on_it() -> None:
    m, a, valid = _clip("02_05")
    con = find_contacts(m, a, valid, m.skeleton.unit_cm)
    back = int(round(FLOOR_WINDOW_S * m.frame_rate))
    k = a.shape[0] // 3
    up = a.copy()
    up[k:, :, con.up] += 30.0 / m.skeleton.unit_cm  # the actor steps onto a 30 cm stage
    after = find_contacts(m, up, valid, m.skeleton.unit_cm)
    assert np.array_equal(after.steps[:k - 1], con.steps[:k - 1])
    assert np.array_equal(after.steps[k + back + 1:], con.steps[k + back + 1:])
    assert con.steps[k + back + 1:].any(axis=0).all()  # both feet planted on the stage


@pytest.mark.parametrize("name", ["06_13", "03_04"])
def test_both_feet_are_planted_on_clips_with_a_low_sample_or_uneven_ground(name: str) -> None:
    # 06_13: one foot's end site dips 13 cm under the floor once; 03_04: uneven ground. With the clip's
    # lowest sample as the floor that foot had 23 (06_13) and 3 (03_04) planted steps in thousands of frames
    m, a, valid = _clip(name)
    con = find_contacts(m, a, valid, m.skeleton.unit_cm)
    assert (con.steps.mean(axis=0) > 0.10).all(), con.steps.mean(axis=0)


def test_a_stream_window_finds_the_whole_clips_contacts() -> None:
    # what stream.StreamEncoder gives a block's correction: 10 s of history and the 1-s block
    m, a, valid = _clip("06_13", 3000)
    whole = find_contacts(m, a, valid, m.skeleton.unit_cm)
    hist, blk = int(10 * m.frame_rate), int(m.frame_rate)
    for s in range(0, a.shape[0], blk):
        e = min(s + blk, a.shape[0])
        w0 = max(s - hist, 0)
        win = find_contacts(m.slice(w0, e), a[w0:e], valid[w0:e], m.skeleton.unit_cm)
        assert np.array_equal(win.feet, whole.feet) and win.up == whole.up
        assert np.array_equal(win.steps[s - w0:e - w0 - 1], whole.steps[s:e - 1]), s


def test_body_height_without_gaps_is_the_gap_path_figure() -> None:
    """context.body_height takes its extents point by point where nothing is missing: the figure the NaN-aware
    reductions give, to the bit, and with gaps those reductions still skip them."""
    from mocapz.codecs.correction.context import body_height

    m, a, valid = _clip("06_13", 1500)
    big = np.where(valid[..., None], a, np.nan)
    ref = float(np.nanmedian(np.nanmax(np.nanmax(big, axis=1) - np.nanmin(big, axis=1), axis=1)))
    assert body_height(a, valid) == ref
    gaps = valid.copy()
    gaps[:, 3] = False  # one point missing everywhere: not part of any extent
    far = a.copy()
    far[:, 3] += 1e6
    assert body_height(far, gaps) == body_height(np.delete(a, 3, axis=1), np.delete(valid, 3, axis=1))
