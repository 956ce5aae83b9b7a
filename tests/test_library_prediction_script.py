"""``scripts/library_prediction.py``: a quick run on one same-subject pair of short CMU clips (09_01, 09_06), its
report and its JSON checked for what they must hold, not for the sizes themselves."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from conftest import data_path

import mocapz
from mocapz.format.container import Container

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

import library_prediction  # noqa: E402

PAIR = ("09_01", "09_06")


def test_quick_pair(tmp_path: Path) -> None:
    """The zero base codes exactly the quant file's correction sections, every coding meets its target, and the
    realisable library is no larger than the single files (nor smaller than the optimistic one)."""
    out, raw = tmp_path / "lp.md", tmp_path / "lp.json"
    assert library_prediction.main(["--quick", "--clips", ",".join(PAIR), "--out", str(out), "--json", str(raw)]) == 0
    text, res = out.read_text(), json.loads(raw.read_text())
    assert set(res["clips"]) == set(PAIR) and res["groups"] == {"09": list(PAIR)}
    for name in PAIR:
        data = mocapz.compress(mocapz.load(data_path(f"cmu/bvh/{name}.bvh")), codec="quant")
        sections = Container.from_bytes(data).sections
        correction = sum(len(v) for k, v in sections.items() if k.startswith("c.") and k != "c.head")
        clip = res["clips"][name]
        assert clip["file"] == len(data) and clip["c_head"] == len(sections["c.head"])
        assert clip["zero"] == clip["file_c"] == correction and clip["identical"] and clip["zero_met"]
        assert all(own["met"] for own in clip["own"].values()) and set(clip["own"]) == {"4", "12", "30"}
        row = f"| {name} | {clip['frames']} | {clip['file']} | {correction} | {clip['c_head']} | {correction} |"
        assert row + " yes | yes |" in text
    codings = res["codings"]
    assert codings and all(r["met"] for r in codings)
    assert {r["method"] for r in codings} == {"win60", "dtw", "oracle"} and any(r["parts"] for r in codings)
    assert {(r["B"], r["A"]) for r in codings} == {PAIR, PAIR[::-1]}
    singles = res["singles"]
    assert singles == sum(c["file"] for c in res["clips"].values())
    lib = res["library"]
    assert lib["optimistic"] <= lib["realisable"] <= singles and res["gain"]["realisable"] >= 1.0
    for r in codings:  # the optimistic library takes each clip's best base (or its zero base)
        if r["method"] != "oracle":
            assert lib["optimistic"] <= singles - res["clips"][r["B"]]["zero"] + r["bytes"] + r["side"] + 1e-9
    assert text.startswith("# Library prediction") and "--quick --clips 09_01,09_06" in text
    assert "all met." in text and "## Conclusion" in text
