"""``scripts/speed.py``: its seek and block-cost measurement (worker, report cells, sums over clips) and a
one-clip run, whose report renders again from its .json. Figures are checked for sense, never for speed."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import DATA, data_path

import mocapz

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

import speed  # noqa: E402


def _clip(tmp_path: Path, frames: int = 500) -> Path:
    """A 500-frame clip at 120 fps (09_06's motion frames forwards and backwards): four 1-s blocks, one 4-s."""
    m = mocapz.load(data_path("cmu/bvh/09_06.bvh"))
    body = m.channels[1:]
    loop = np.concatenate([body, body[::-1]])
    values = np.concatenate([loop] * -(-frames // loop.shape[0]))[:frames]
    path = tmp_path / "clip.bvh"
    mocapz.save(m.with_values(values), path)
    return path


@pytest.mark.parametrize(("codec", "default_blocks"), [("lossless", 3), ("quant", 1)])  # lossless: 128-frame blocks
def test_seek_worker(tmp_path: Path, codec: str, default_blocks: int) -> None:
    out = speed.worker({"path": str(_clip(tmp_path)), "codec": codec, "mode": "seek", "repeat": 1})
    assert out["frames"] == 500 and out["frame_rate"] == pytest.approx(120.0)
    assert set(speed.BLOCKS) <= set(out)
    assert [out[k]["blocks"] for k in ("default", "1s", "4s", "one")] == [default_blocks, 4, 1, 1]
    assert out["1s"]["block_frames"] == 120
    for label in speed.BLOCKS:
        assert out[label]["bytes"] > 0 and out[label]["encode_s"] > 0
    for label in speed.SEEKED:
        rec = out[label]
        assert rec["seek_frames"] == 20 and rec["seek_starts"] == [0, 120, 240, 360, 480]
        assert len(rec["seek_all_s"]) == 5 and all(t > 0 for t in rec["seek_all_s"])
        assert rec["seek_s"] == sorted(rec["seek_all_s"])[2] and rec["decode_s"] > 0 and rec["rounds"] >= 1
        pct = speed.seek_pct(out, label)
        assert pct is not None and math.isfinite(pct) and pct > 0
        assert speed.seek_fps(out, label) == pytest.approx(20 / rec["seek_s"])
        assert len(rec["reader_all_s"]) == 5 and rec["reader_s"] == sorted(rec["reader_all_s"])[2] > 0
        opened = speed.seek_pct(out, label, "reader_s")
        assert opened is not None and 0 < opened
    cost = speed.block_cost(out, "1s")
    assert cost is not None and math.isfinite(cost) and abs(cost) < 50
    assert out["4s"]["bytes"] == out["one"]["bytes"] and speed.block_cost(out, "4s") == 0.0  # both one block
    cells = speed.seek_cells({"seek": out}, None)
    assert len(cells) == 8 and cells[0] == (f"{128 / 120:g} s (3 blocks)" if default_blocks == 3 else "one block")
    assert cells[-1] == "+0.0 % (one block)"


def test_seek_starts() -> None:
    assert speed.seek_starts(500) == [0, 120, 240, 360, 480]
    assert speed.seek_starts(20) == [0] and speed.seek_starts(10, 10) == [0]
    assert speed.seek_starts(4906)[-1] == 4886


def _seek(seek_s: float, decode_s: float, sizes: tuple[int, int, int, int], blocks: int) -> dict[str, Any]:
    recs = {label: {"bytes": b, "encode_s": 0.1, "blocks": blocks if label in ("default", "1s") else 1,
                    "block_frames": 120} for label, b in zip(speed.BLOCKS, sizes, strict=True)}
    for label in speed.SEEKED:
        recs[label].update(seek_frames=20, seek_s=seek_s, reader_s=seek_s / 2, decode_s=decode_s)
    return {"frames": 1000, "frame_rate": 120.0, **recs}


def test_sums_over_clips() -> None:
    """Over the CMU clips: seek and decode times and bytes are added up; a failed clip is left out."""
    rows = [{"clip": "a", "codec": "lossless", "frames": 1000, "seek": _seek(0.01, 0.5, (990, 990, 1000, 1000), 8)},
            {"clip": "b", "codec": "lossless", "frames": 1000, "seek": _seek(0.03, 0.5, (2010, 2010, 2000, 2000), 8)},
            {"clip": "c", "codec": "lossless", "frames": 1000, "seek": {"over": 300.0}}]
    (agg,) = speed.summarise_seek(rows, ["lossless"])
    assert agg["frames"] == 2000
    assert speed.seek_fps(agg["seek"], "default") == pytest.approx(40 / 0.04)
    assert speed.seek_pct(agg["seek"], "default") == pytest.approx(4.0)
    assert speed.block_cost(agg["seek"], "1s") == pytest.approx(0.0)
    lines = speed.seek_table([agg, *rows], with_clip=True)
    assert speed.seek_pct(agg["seek"], "default", "reader_s") == pytest.approx(2.0)
    assert lines[2] == ("| CMU clips | lossless | 2,000 | 1 s (16 blocks) | 1,000 x1.00 | 4.0 % | 2.0 % | "
                        "1,000 x1.00 | 4.0 % | +0.0 % | +0.0 % (one block) |")
    assert lines[3].startswith("| a | lossless | 1,000 | 1 s (8 blocks) | 2,000 x1.00 | 2.0 % | 1.0 % |")
    assert lines[5] == "| c | lossless | 1,000 | " + " | ".join(["over 300 s"] * 8) + " |"


def test_one_clip_run(tmp_path: Path) -> None:
    """A real run on one short clip, the lossless codec only: every column filled, the report renders again
    from the .json, and no sentence says seek is not measured."""
    assert speed.DATA.resolve() == DATA.resolve()
    out = tmp_path / "speed.md"
    assert speed.main(["--clips", "09_06", "--codecs", "lossless", "--repeat", "1", "--no-synthetic",
                       "--out", str(out)]) == 0
    text = out.read_text()
    saved = json.loads(out.with_suffix(".json").read_text())
    (row,) = saved["rows"]
    for part in ("fixed", "cli", "seek"):
        assert "error" not in row[part] and "over" not in row[part], row[part]
    seek = row["seek"]
    assert seek["frames"] == 142 and seek["default"]["blocks"] == 1  # under 2 s: one block
    for label in speed.SEEKED:
        assert seek[label]["seek_s"] > 0 and math.isfinite(speed.seek_pct(seek, label) or math.nan)
    assert "### Seek and blocks, per clip" in text and "### Seek and blocks, CMU clips all together" in text
    assert "| 09_06 | lossless | 142 | one block | " in text
    assert "not measured" not in text and "not implemented" not in text
    again = tmp_path / "again.md"
    assert speed.main(["--render", str(out.with_suffix(".json")), "--out", str(again)]) == 0
    assert again.read_text() == text


def test_library_command(tmp_path: Path) -> None:
    """The library in one command: one ``mocapz compress`` over two real clips writes both files (timed), a
    failing one reports its error line, and the table gives frames/s over the clips beside the lossless codec's."""
    clips = [data_path("cmu/bvh/09_06.bvh"), data_path("cmu/bvh/09_01.bvh")]
    done = speed.run_library(clips, "lossless", 1, 120.0)
    assert set(done) == {"cli_s"} and done["cli_s"] > 0
    broken = tmp_path / "broken.bvh"
    broken.write_text("HIERARCHY\nROOT\n")
    failed = speed.run_library([clips[0], broken], "lossless", 1, 120.0)
    assert "broken.bvh" in failed["error"]
    rows = [{"clip": c, "codec": "lossless", "frames": n, "cli": {"cli_s": 0.5}} for c, n in (("a", 142), ("b", 149))]
    lines = speed.library_table(rows, {"lossless": {"cli_s": 1.0}, "quant": failed})
    assert lines[2] == "| lossless | 2 | 291 | 291 x1.00 | 291 x1.00 |"
    assert lines[3].startswith("| quant | 2 | 291 | error: ") and "broken.bvh" in lines[3]


def test_targets_commands(tmp_path: Path) -> None:
    """Each target's whole commands: one ``mocapz compress`` a clip with the target's flags (a real short clip:
    the file it writes meets the target), their times added up, a failing clip reporting its error, and the table
    beside the default target's column and the lossless codec's one-clip commands."""
    clip = data_path("cmu/bvh/09_06.bvh")
    got = speed.run_targets([clip], ["lossless", "quant"], 1, 120.0)
    assert set(got) == {"quant"} and set(got["quant"]) == set(speed.TARGETS)
    assert all(m["cli_s"] > 0 for m in got["quant"].values())
    assert "cli_s" in speed.run_cli(clip, "quant", 1, 120.0, tmp_path, ["--max-arms", "5mm"])
    written = mocapz.decompress((tmp_path / "cli.quant.mcz").read_bytes())
    assert mocapz.evaluate(mocapz.load(clip), written).arms_cm <= 0.5
    broken = tmp_path / "broken.bvh"
    broken.write_text("HIERARCHY\nROOT\n")
    failed = speed.run_targets([clip, broken], ["quant"], 1, 120.0)["quant"]
    assert all("broken.bvh" in m["error"] for m in failed.values())
    rows = [{"clip": "a", "codec": c, "frames": 142, "cli": {"cli_s": t}} for c, t in (("lossless", 0.5), ("quant", 1))]
    mine = {"max distortion 0.36 %": {"cli_s": 2.0}, "max ARMS 5 mm": failed["max ARMS 5 mm"]}
    lines = speed.targets_table(rows, {"quant": mine})
    assert lines[2].startswith("| quant | 142 | 142 x0.50 | 71 x0.25 | error: ") and "broken.bvh" in lines[2]
