"""``scripts/memory.py``: a quick run on a short clip (09_06) with two codecs, its table checked for what it must
hold (every case a row, figures that fit together), and a failing command named, not the sizes themselves."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

import memory  # noqa: E402


def test_quick_run(tmp_path: Path) -> None:
    out = tmp_path / "m.md"
    assert memory.main(["--clip", "09_06", "--no-long", "--repeat", "1", "--codecs", "lossless,quant",
                        "--out", str(out)]) == 0
    rows = [ln.split("|")[1:-1] for ln in out.read_text().splitlines() if ln.startswith("| 09_06 |")]
    cases = [c for c in memory.CASES if c[0] in ("lossless", "quant")]
    assert [(r[2].strip(), r[3].strip()) for r in rows] == \
        [(c, " ".join(o) or ("(exact)" if c == "lossless" else "(default target)")) for c, o in cases]
    for r in rows:
        assert r[1].strip() == "142"
        rss, anon, file, secs = (float(r[i]) for i in (4, 5, 6, 7))
        assert 20 < rss < 2000 and 0 < anon < rss and 0 < file < rss and secs > 0


def test_a_failing_command_is_named(tmp_path: Path) -> None:
    missing = tmp_path / "none.bvh"
    with pytest.raises(RuntimeError, match="none.bvh"):
        memory.run([sys.executable, "-m", "mocapz", "compress", str(missing), "-o", str(tmp_path / "o.mcz")])
