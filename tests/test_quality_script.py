"""``scripts/quality.py``: its records are the codec's verified figures, its output order does not depend on
the number of processes, and a refused target is a row that says so."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest
from conftest import DATA

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

import quality  # noqa: E402
import quality_report  # noqa: E402

ARGS = ["--clips", "09_06,other/markers/btkdata/Gait.trc", "--codecs", "quant,pga", "--frames", "40", "-q"]


def _run(tmp_path: Path, name: str, *extra: str) -> tuple[str, dict[str, Any]]:
    out, js = tmp_path / f"{name}.md", tmp_path / f"{name}.json"
    assert quality.main([*ARGS, "--out", str(out), "--json", str(js), *extra]) == 0
    return out.read_text(), json.loads(js.read_text())


def test_records_order_and_figures(tmp_path: Path) -> None:
    assert quality.DATA == DATA
    text, doc = _run(tmp_path, "one")
    recs = doc["records"]
    keys = [(r["clip"], r["codec"], r["target"]) for r in recs]
    assert keys == [(c, k, t) for c in ("09_06", "other/markers/btkdata/Gait.trc") for k in ("quant", "pga")
                    for t in ("1cm", "1mm", "d0.36")]
    by = {k: r for k, r in zip(keys, recs, strict=True)}
    assert by[("other/markers/btkdata/Gait.trc", "pga", "1cm")]["status"] == "n/a"  # pga: skeletons only
    for r in recs:
        assert r["frames"] == 40
        if r["status"] != "ok":
            continue
        assert r["ratio"] == pytest.approx(r["raw_bytes"] / r["compressed_bytes"])
        _, figure, bound = quality.TARGETS[r["target"]]
        assert r[figure] <= bound * (1 + quality.SLACK)
        for k in ("foot_skate", "foot_skate_window", "jitter_pct", "arms_cm", "encode_s"):
            assert k in r
    q = by[("09_06", "quant", "1cm")]
    assert q["status"] == "ok"
    row = f"| 09_06 | quant | max error 1 cm | ok | {quality_report.fmt(q['ratio'])} | {q['ratio'] / 6.5:.2f} |"
    assert row in text
    assert "not measured here" in text and "## Targets not met" in text
    # two processes: the same records in the same order (times aside)
    _, doc2 = _run(tmp_path, "two", "--jobs", "2")
    strip = ("encode_ms_per_frame", "decode_ms_per_frame", "encode_s", "seconds", "deterministic")
    assert [{k: v for k, v in r.items() if k not in strip} for r in doc2["records"]] == \
        [{k: v for k, v in r.items() if k not in strip} for r in recs]


def test_refused_target_is_a_row(tmp_path: Path) -> None:
    """A TargetError from the codec becomes a "failed" cell and a row of the failures, with its message."""
    task = quality.Task(0, "cmu/bvh/09_06.bvh", "quant", "1cm", 30, 60.0)
    rec = quality.run_task(task)
    assert rec["status"] == "ok"
    failed = {**{k: v for k, v in rec.items() if k in ("clip", "path", "frames", "kind", "raw_bytes", "unit_cm",
                                                        "frame_rate")},
              "codec": "pga", "target": "1cm", "status": "target failed", "message": "cannot meet | the target"}
    run = {"command": "x", "started": "now", "duration_s": 1.0, "machine": {}, "mocapz_version": "0",
           "frames_cap": 30, "jobs": 1, "timeout_s": 60.0, "codecs": ["quant", "pga"], "targets": ["1cm"],
           "clips": ["09_06"]}
    text = quality_report.render([rec, failed], run)
    assert "| 09_06 | 30 | 6.5 |" in text and "| failed |" in text
    assert "| 09_06 | pga | max error 1 cm | target failed | cannot meet / the target |" in text
    # the total over the clips: quant's ratio against ACL's on the same clip; pga has none
    ratio = quality_report.fmt(rec["ratio"])
    assert f"| **over the 1** | 30 | 6.5 | {ratio} ({rec['ratio'] / 6.5:.2f}×) | none |" in text


def test_clip_names() -> None:
    assert quality.resolve_clips("09_06,cmu14", False)[:2] == ["cmu/bvh/09_06.bvh", "cmu/bvh/01_01.bvh"]
    assert len(quality.resolve_clips(None, False)) == len(quality.CMU14) + len(quality.OTHERS)
    assert all((DATA / c).is_file() for c in quality.CMU14 + quality.OTHERS + quality.QUICK_CLIPS)
    with pytest.raises(SystemExit, match="no clip"):
        quality.resolve_clips("nope", False)
