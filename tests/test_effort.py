"""The ``effort`` option (issue 12: encode speed with a target): ``fast`` codes a long clip once at one lifting
depth, ``best`` codes every setting on the whole clip, and every effort meets the target with
the feet held, on real clips."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import data_path
from test_cli import RUN, assert_one_line_error, mocapz_cli
from test_targets import added_skate

import mocapz
from mocapz.codecs.correction import rounds as rounds_module
from mocapz.codecs.correction import search
from mocapz.codecs.correction.fit import lifting_levels
from mocapz.codecs.correction.search import FAST_DEPTH
from mocapz.format.container import Container
from mocapz.format.entropy import read_uvarint
from mocapz.model.motion import AnyMotion


def _fits(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The lifting depth of every correction :func:`search.fit` codes from now on."""
    depths: list[int] = []
    real = search.fit

    def counted(*args, **kw):  # noqa: ANN002, ANN003, ANN202
        depths.append(args[4] if len(args) > 4 else kw["depth"])  # (clip, base, bound, relax_by, depth)
        return real(*args, **kw)

    monkeypatch.setattr(search, "fit", counted)
    return depths


def _depth(data: bytes) -> int:
    """The lifting depth a file's correction was coded with (its ``c.head``: format, base kind, depth, ...)."""
    head = Container.from_bytes(data).sections["c.head"]
    pos = 0
    for _ in range(2):
        _, pos = read_uvarint(head, pos)
    return read_uvarint(head, pos)[0]


def _max_error_cm(m: AnyMotion, data: bytes) -> float:
    rep = mocapz.evaluate(m, mocapz.decompress(data))
    assert rep.max_err_cm is not None
    return rep.max_err_cm


@pytest.mark.slow
def test_fast_codes_a_long_clip_once_and_best_is_never_larger(monkeypatch: pytest.MonkeyPatch) -> None:
    m = mocapz.load(data_path("cmu/bvh/06_13.bvh"))  # 4,906 frames: medium chooses on two windows
    fits = _fits(monkeypatch)
    sizes = {}
    for effort in ("fast", "medium", "best"):
        fits.clear()
        data = mocapz.compress(m, codec="quant", max_error="1cm", effort=effort)
        sizes[effort] = len(data)
        assert _max_error_cm(m, data) <= 1.0 + 1e-9, effort
        assert added_skate(m, mocapz.decompress(data)) <= 0.5, effort
        if effort == "fast":
            assert fits == [lifting_levels(m.frame_rate) + FAST_DEPTH] == [_depth(data)]  # one fit, one depth
        else:
            assert len(fits) >= 3  # medium's windows and its whole clip; best: each depth, whole
    # a max error bound's fit depends on the setting alone, and best codes medium's choice among the others
    assert sizes["best"] <= sizes["medium"]


@pytest.mark.parametrize("codec", ["pga", "patterns"])
def test_fast_meets_the_target_with_a_model(codec: str, monkeypatch: pytest.MonkeyPatch) -> None:
    m = mocapz.load(data_path("cmu/bvh/09_06.bvh"))
    fits = _fits(monkeypatch)
    data = mocapz.compress(m, codec=codec, max_error="1cm", effort="fast")
    assert _max_error_cm(m, data) <= 1.0 + 1e-9
    assert set(fits) == {lifting_levels(m.frame_rate) + FAST_DEPTH}  # the model and the zero base, one depth each
    assert len(fits) <= 2


def test_an_unknown_effort_is_refused_on_one_line(tmp_path: Path) -> None:
    out = tmp_path / "x.mcz"
    res = mocapz_cli("compress", data_path(RUN), "-o", out, "--codec", "quant", "--effort", "max")
    assert "fast, medium, best" in assert_one_line_error(res, "effort", code=2) and not out.exists()


def test_the_effort_script_measures_and_reports(tmp_path: Path) -> None:
    """``scripts/effort.py`` on one clip: every effort's file checked against the target, one table row per
    codec whose totals are the clips' sums."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    import effort  # noqa: PLC0415

    rows = effort.measure("quant", ["fast", "medium"], "1cm", [data_path(RUN)])
    assert [r["clip"] for r in rows] == ["09_06"] and rows[0]["frames"] == 142
    for e in ("fast", "medium"):
        size, seconds, err_cm, _ = rows[0][e]
        assert size > 0 and seconds > 0 and err_cm <= 1.0 + 1e-9
    text = effort.report({"quant": rows}, ["fast", "medium"], "1cm", "--clips 09_06")
    assert f"| quant | {rows[0]['fast'][0]:,} |" in text and "| quant | 09_06 | 142 |" in text


@pytest.mark.slow
def test_fast_falls_back_a_depth_when_its_rounds_run_out(monkeypatch: pytest.MonkeyPatch) -> None:
    """CMU lambada at 1 cm, lifting depth 5, its verification rounds cut to 2: they run out with the levels up
    (the 40 rounds themselves did until the closed loop aimed its one- and two-axis joints: 88 kB, depth 4 in
    18 kB). Fast, made to start at depth 5, codes depth 4 as well and keeps the smaller."""
    m = mocapz.load(data_path("cmu/asfamc/lambada.amc"))
    monkeypatch.setattr(search, "FAST_DEPTH", 5 - lifting_levels(m.frame_rate))
    monkeypatch.setattr(rounds_module, "MAX_ROUNDS", 2)
    made: list[tuple[int, int, bool, bool]] = []  # (depth, bytes of the correction, rounds settled, 1 cm met)
    real = search.fit

    def recorded(*args, **kw):  # noqa: ANN002, ANN003, ANN202
        cor = real(*args, **kw)
        made.append((cor.depth, cor.size, cor.settled, cor.errors.max_error * m.unit_cm <= 1.0 + 1e-9))
        return cor

    monkeypatch.setattr(search, "fit", recorded)
    data = mocapz.compress(m, codec="quant", max_error="1cm", effort="fast")
    assert [c[0] for c in made] == [5, 4] and not made[0][2]  # depth 5 ran out, so depth 4 was coded
    assert _depth(data) == min((c for c in made if c[3]), key=lambda c: c[1])[0]  # the smaller that meets 1 cm
    assert _max_error_cm(m, data) <= 1.0 + 1e-9


def test_the_default_effort_is_fast() -> None:
    """No ``effort`` given: fast (one lifting depth), the same bytes as asking for it."""
    m = mocapz.load(data_path(RUN))
    assert mocapz.compress(m, codec="quant") == mocapz.compress(m, codec="quant", effort="fast")
    assert mocapz.compress(m, codec="quant") != mocapz.compress(m, codec="quant", effort="medium")
