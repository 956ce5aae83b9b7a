"""``mocapz bench``: its figures equal compress + decompress + eval, a quick run writes its report, failing
codecs are recorded without stopping the run, and the rate-distortion interpolation behaves."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner
from conftest import data_path

import mocapz
from mocapz.bench import run_bench, write_report
from mocapz.bench.corpus import default_paths, discover, quick_selection
from mocapz.bench.curves import corpus_ratio, pareto, ratio_at
from mocapz.bench.sweeps import DEFAULT_CODECS, parse_codecs
from mocapz.cli.bench import bench
from mocapz.cli.main import cli
from mocapz.codecs import _REGISTRY, CodecInfo, get_codec

SHORT = "cmu/bvh/09_06.bvh"  # 142 frames
SHORT2 = "cmu/bvh/09_01.bvh"  # 149 frames
SCORES = ("distortion_pct", "arms", "max_err", "p99_err", "bone_len_err", "foot_skate", "jitter_pct", "max_err_cm",
          "arms_cm")
SIZES = ("raw_bytes", "compressed_bytes", "ratio", "ratio_file", "bytes_per_second")


def _cli(*args: str) -> Any:
    result = CliRunner().invoke(cli, list(args), catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result


def _record(doc: dict[str, Any], codec: str, **setting: Any) -> dict[str, Any]:
    recs = [r for r in doc["records"] if r["codec"] == codec and r["setting"] == setting]
    assert len(recs) == 1, (codec, setting)
    assert recs[0]["status"] == "ok", recs[0].get("error")
    return recs[0]


# ---------------------------------------------------------------- the acceptance test
@pytest.mark.parametrize(("codec", "setting", "flags"), [
    ("quant", {"max_error": "1cm"}, ["--max-error", "1cm"]),
    ("pga", {"max_error": "1cm"}, ["--max-error", "1cm"]),
])
def test_report_equals_compress_decompress_eval(tmp_path: Path, codec: str, setting: dict[str, Any],
                                                flags: list[str]) -> None:
    """The report's numbers for a setting are what the command line gives for the same setting."""
    src = data_path(SHORT)
    doc = run_bench([src], [codec], quick=True, progress=False)
    written = write_report(doc, tmp_path / "report", plots=False)
    saved = json.loads(written["results"].read_text())
    rec = _record(saved, codec, **setting)
    mcz, bvh = tmp_path / "clip.mcz", tmp_path / "clip.bvh"
    _cli("compress", str(src), "-o", str(mcz), "--codec", codec, *flags)
    _cli("decompress", str(mcz), "-o", str(bvh))
    ev = json.loads(_cli("eval", str(src), str(mcz), "--json").output)
    assert mcz.stat().st_size == rec["compressed_bytes"]
    for key in SIZES + SCORES:
        assert ev[key] == pytest.approx(rec[key], rel=1e-12, abs=1e-15), key
    # the decoded file, as written, scores the same up to the text precision of the BVH writer
    ev_file = json.loads(_cli("eval", str(src), str(bvh), "--json").output)
    assert ev_file["distortion_pct"] == pytest.approx(rec["distortion_pct"], rel=1e-3)
    assert ev_file["max_err"] == pytest.approx(rec["max_err"], rel=1e-3)
    # the report's tables show the same figure
    report = written["report"].read_text()
    assert "cmu/bvh/09_06.bvh" in report and codec in report


# ---------------------------------------------------------------- a quick run through the command
@pytest.mark.slow
def test_quick_run_two_clips(tmp_path: Path) -> None:
    out = tmp_path / "bench"
    t0 = time.perf_counter()
    result = CliRunner().invoke(bench, [str(data_path(SHORT)), str(data_path(SHORT2)), "--quick", "-o", str(out),
                                        "--no-progress"], catch_exceptions=False)
    elapsed = time.perf_counter() - t0
    assert result.exit_code == 0, result.output
    doc = json.loads((out / "results.json").read_text())
    assert doc["mocapz_version"] == mocapz.__version__ and doc["machine"]["cores"]
    assert [c["clip"] for c in doc["clips"]] == ["cmu/bvh/09_01.bvh", "cmu/bvh/09_06.bvh"]
    codecs = {r["codec"] for r in doc["records"]}
    assert codecs == set(DEFAULT_CODECS)
    for r in doc["records"]:
        if r["codec"] != "patterns":  # a colleague's codec in progress: its failures are recorded, not fatal
            assert r["status"] == "ok", (r["codec"], r["label"], r.get("error"))
        if r["status"] == "ok":
            assert r["ratio"] == pytest.approx(r["raw_bytes"] / r["compressed_bytes"])
            assert r["encode_ms_per_frame"] > 0 and r["decode_ms_per_frame"] > 0
            assert r["decode_vs_lossless"] is not None and r["deterministic"] is not False
    lossless = [r for r in doc["records"] if r["codec"] in ("lossless", "gzip", "bzip2", "xz", "zstd")]
    assert all(r["distortion_pct"] == 0 and r["max_err"] == 0 for r in lossless)
    report = (out / "report.md").read_text()
    for heading in ("## Corpus: ratio at fixed error", "## Published operating points", "## Per clip", "## Speed"):
        assert heading in report
    assert "*PGA paper, Table 2* (published, same clip)" in report  # 09_06 is the paper's clip
    for png in ("rd_distortion.png", "rd_max_error.png", "speed.png"):
        data = (out / png).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) < 150_000
    assert elapsed < 300  # about 10 s of CPU; generous for loaded shared machines


# ---------------------------------------------------------------- robustness
def _broken_encode(motion: Any, **options: Any) -> dict[str, bytes]:
    raise RuntimeError("this codec always fails")


def _slow_encode(motion: Any, **options: Any) -> dict[str, bytes]:
    time.sleep(5)
    return {}


def test_failures_are_recorded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    lossless = get_codec("lossless")
    broken = CodecInfo("broken", 1, ("skeleton", "markers"), _broken_encode, lossless.decode, {})
    slow = CodecInfo("slow", 1, ("skeleton", "markers"), _slow_encode, lossless.decode, {})
    monkeypatch.setitem(_REGISTRY, "broken", lambda: broken)
    monkeypatch.setitem(_REGISTRY, "slow", lambda: slow)
    doc = run_bench([data_path(SHORT)], ["broken", "slow", "quant"], quick=True, timeout=3.0, progress=False)
    bad = {r["codec"]: r for r in doc["records"] if r["status"] == "failed"}
    assert set(bad) == {"broken", "slow"}
    assert bad["broken"]["error"] == "RuntimeError: this codec always fails"
    assert "timed out" in bad["slow"]["error"]
    assert all(r["status"] == "ok" for r in doc["records"] if r["codec"] in ("lossless", "quant"))
    report = write_report(doc, tmp_path, plots=False)["report"].read_text()
    assert "this codec always fails" in report.split("## Failures", 1)[1]


def test_unreadable_clip_recorded(tmp_path: Path) -> None:
    bad = tmp_path / "broken.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n")
    doc = run_bench([bad, data_path(SHORT)], ["quant"], quick=True, progress=False)
    assert [r["codec"] for r in doc["records"] if r["status"] == "failed"] == ["(load)"]
    assert len(doc["clips"]) == 1


def test_codec_list() -> None:
    assert parse_codecs(None)[0] == "lossless"
    assert parse_codecs("quant,pca") == ["lossless", "quant", "pca"]
    assert parse_codecs("zstd,lossless,zstd") == ["lossless", "zstd"]
    with pytest.raises(mocapz.OptionError, match="unknown codec"):
        parse_codecs("quant,nope")


def test_default_corpus_and_quick_selection() -> None:
    clips = discover(default_paths())
    ids = [c.clip_id for c in clips]
    assert "cmu/bvh/09_06.bvh" in ids and "cmu/c3d/01_01.c3d" in ids and "cmu/asfamc/01_01.amc" in ids
    assert all(i.startswith("cmu/") for i in ids)
    quick = quick_selection(clips, explicit=False)
    exts = sorted(c.ext for c in quick)
    assert exts == [".amc", ".bvh", ".bvh", ".bvh", ".c3d"]
    assert "cmu/bvh/09_06.bvh" in [c.clip_id for c in quick]


# ---------------------------------------------------------------- rate-distortion interpolation
def test_pareto_front() -> None:
    pts = [(1.0, 10.0), (2.0, 8.0), (0.5, 5.0), (2.0, 20.0), (4.0, 30.0), (3.0, 15.0)]
    assert pareto(pts) == [(0.5, 5.0), (1.0, 10.0), (2.0, 20.0), (4.0, 30.0)]


def test_ratio_at_interpolates_on_the_front() -> None:
    pts = [(0.1, 10.0), (1.0, 100.0), (0.5, 20.0)]
    assert ratio_at(pts, 0.05) is None  # never reached: no extrapolation below the best quality
    assert ratio_at(pts, 0.1) == pytest.approx(10.0)
    # log-log between (0.5, 20) and (1, 100)
    mid = math.exp(math.log(20) + math.log(0.7 / 0.5) / math.log(2.0) * math.log(5.0))
    assert ratio_at(pts, 0.7) == pytest.approx(mid)
    assert ratio_at(pts, 10.0) == pytest.approx(100.0)  # no extrapolation past the coarsest setting
    assert ratio_at([(0.0, 3.0), (2.0, 9.0)], 1.0) == pytest.approx(3.0 * 3.0 ** 0.5)  # from an exact point
    levels = [0.1, 0.2, 0.4, 0.8, 1.6]
    values = [ratio_at(pts, lv) for lv in levels]
    assert values == sorted(values)


def test_corpus_ratio_is_size_weighted() -> None:
    ratio, used = corpus_ratio([(1000, 10.0), (3000, 30.0), (500, None)])
    assert used == 2
    assert ratio == pytest.approx(4000 / (100 + 100))
