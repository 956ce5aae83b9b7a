"""Batch compression (``mocapz compress DIR -o OUTDIR``): serial, --jobs 2 and Dask give the same bytes."""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.cli.batch import run_batch_compress
from mocapz.errors import MocapzError, OptionError
from mocapz.parallel.discover import discover, plan
from mocapz.parallel.folder import compress_folder
from mocapz.parallel.load import load_many
from mocapz.parallel.pool import Pool
from mocapz.parallel.worker import WorkerCrashed

SHORT_CLIPS = {  # a few short shared clips, copied into tmp_path (never into the repo)
    "cmu/bvh/09_06.bvh": "09_06.bvh",
    "cmu/bvh/09_01.bvh": "run/09_01.bvh",
    "cmu/bvh/02_03.bvh": "run/02_03.bvh",
    "cmu/asfamc/backflip.amc": "acro/backflip.amc",
    "cmu/asfamc/backflip.asf": "acro/backflip.asf",
    "other/markers/btkdata/Gait.trc": "markers/Gait.trc",
}
EXPECTED = ["09_06.bvh", "acro/backflip.amc", "markers/Gait.trc", "run/02_03.bvh", "run/09_01.bvh"]


@pytest.fixture
def library(tmp_path: Path) -> Path:
    root = tmp_path / "in"
    for src, rel in SHORT_CLIPS.items():
        dst = root / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(data_path(src), dst)
    return root


def _outputs(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# ------------------------------------------------------------------ discovery and output names
def test_discover_is_recursive_sorted_and_skips_other_files(library: Path) -> None:
    (library / ".hidden").mkdir()
    shutil.copyfile(library / "09_06.bvh", library / ".hidden" / "x.bvh")
    shutil.copyfile(library / "09_06.bvh", library / ".09_06.bvh.tmp.bvh")
    (library / "notes.txt").write_text("not motion")
    shutil.copyfile(library / "09_06.bvh", library / "run" / "UPPER.BVH")
    names = [p.relative_to(library).as_posix() for p in discover(library)]
    assert names == sorted(EXPECTED + ["run/UPPER.BVH"], key=lambda n: n.split("/"))
    assert names == [p.relative_to(library).as_posix() for p in discover(library)]  # deterministic


def test_plan_mirrors_layout_and_separates_same_stems(library: Path, tmp_path: Path) -> None:
    shutil.copyfile(library / "markers" / "Gait.trc", library / "09_06.trc")
    jobs = plan(library, tmp_path / "out")
    outs = {j.name: Path(j.output).relative_to((tmp_path / "out").resolve()).as_posix() for j in jobs}
    assert outs["run/09_01.bvh"] == "run/09_01.bvh.mcz"
    assert outs["acro/backflip.amc"] == "acro/backflip.amc.mcz"
    assert outs["09_06.bvh"] == "09_06.bvh.mcz" and outs["09_06.trc"] == "09_06.trc.mcz"
    assert [j.index for j in jobs] == list(range(len(jobs)))


def test_missing_folder_and_unknown_codec_are_batch_errors(tmp_path: Path, library: Path) -> None:
    with pytest.raises(MocapzError, match="no such folder"):
        compress_folder(tmp_path / "nope", tmp_path / "out")
    with pytest.raises(OptionError, match="unknown codec"):
        compress_folder(library, tmp_path / "out", codec="nope")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


# ------------------------------------------------------------------ same bytes whatever the parallelism
def test_serial_and_process_pool_write_identical_bytes(library: Path, tmp_path: Path) -> None:
    serial = compress_folder(library, tmp_path / "serial", jobs=1)
    pooled = compress_folder(library, tmp_path / "jobs2", jobs=2)
    assert serial.mode == "serial" and pooled.mode == "processes" and pooled.workers == 2
    assert not serial.failed and not pooled.failed
    a, b = _outputs(tmp_path / "serial"), _outputs(tmp_path / "jobs2")
    assert sorted(a) == sorted(n + ".mcz" for n in EXPECTED)
    assert a == b
    assert [r.name for r in serial.results] == EXPECTED == [r.name for r in pooled.results]
    assert serial.frames == pooled.frames > 0
    # lossless: the files decode to the inputs
    back = mocapz.decompress((tmp_path / "jobs2" / "run" / "02_03.bvh.mcz").read_bytes())
    assert np.array_equal(back.channels, mocapz.load(library / "run" / "02_03.bvh").channels)


@pytest.mark.slow
def test_dask_local_cluster_writes_identical_bytes(library: Path, tmp_path: Path) -> None:
    pytest.importorskip("distributed", reason="dask[distributed] is not installed (pip install 'mocapz[dask]')")
    for codec in ("lossless", "quant"):
        compress_folder(library, tmp_path / f"serial-{codec}", codec=codec, jobs=1)
    with Pool(jobs=2, scheduler="local") as pool:
        assert pool.mode == "dask" and pool.workers == 2
        assert pool._client.scheduler.address.startswith("tcp://127.0.0.1:")
        for codec in ("lossless", "quant"):
            rep = compress_folder(library, tmp_path / f"dask-{codec}", codec=codec, pool=pool)
            assert not rep.failed, rep.failed
            assert _outputs(tmp_path / f"dask-{codec}") == _outputs(tmp_path / f"serial-{codec}")
    assert _outputs(tmp_path / "dask-lossless") != _outputs(tmp_path / "dask-quant")


def test_scheduler_needs_dask(monkeypatch: pytest.MonkeyPatch, library: Path, tmp_path: Path) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(OptionError, match=r"mocapz\[dask\]"):
        compress_folder(library, tmp_path / "out", scheduler="local")


# ------------------------------------------------------------------ failures
def test_corrupt_clip_is_reported_and_others_complete(library: Path, tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    text = (library / "09_06.bvh").read_text()
    (library / "run" / "broken.bvh").write_text(text[: len(text) // 3])  # cut inside the hierarchy or motion
    (library / "garbage.c3d").write_bytes(os.urandom(3000))
    rc = run_batch_compress(library, tmp_path / "out", "lossless", {}, 2, None, False, False)
    out, err = capsys.readouterr()
    assert rc == 1
    errors = [line for line in err.splitlines() if line.startswith("mocapz: error:")]
    assert len(errors) == 2
    assert str(library / "garbage.c3d") in errors[0] and "not a C3D file" in errors[0]
    assert str(library / "run" / "broken.bvh") in errors[1]
    assert "5/7 clips compressed, 2 FAILED" in err and out == ""  # messages go to stderr, stdout is for data
    written = _outputs(tmp_path / "out")
    assert sorted(written) == sorted(n + ".mcz" for n in EXPECTED)


def test_existing_outputs_kept_without_force(library: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "out"
    (out_dir / "run").mkdir(parents=True)
    (out_dir / "run" / "09_01.bvh.mcz").write_bytes(b"old")
    with pytest.raises(MocapzError, match="09_01.bvh.mcz: output exists"):  # found before any clip is read
        run_batch_compress(library, out_dir, "lossless", {}, 1, None, False, False)
    assert (out_dir / "run" / "09_01.bvh.mcz").read_bytes() == b"old"
    assert not (out_dir / "run" / "02_03.bvh.mcz").exists()
    assert run_batch_compress(library, out_dir, "lossless", {}, 1, None, True, False) == 0
    assert (out_dir / "run" / "09_01.bvh.mcz").read_bytes()[:3] != b"old"


def test_json_report(library: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (library / "empty.trc").write_text("")
    rc = run_batch_compress(library, tmp_path / "out", "lossless", {}, 1, None, False, True)
    out, err = capsys.readouterr()
    d = json.loads(out)
    assert rc == 1 and d["clips"] == 6 and d["failed"] == 1 and d["ok"] == 5
    assert d["failures"][0]["name"] == "empty.trc" and "empty" in d["failures"][0]["error"]
    assert [r["name"] for r in d["results"]] == sorted(EXPECTED + ["empty.trc"], key=lambda n: n.split("/"))
    assert d["frames"] == sum(r["frames"] for r in d["results"]) and d["frames_per_second"] > 0
    assert "empty.trc" in err


# ------------------------------------------------------------------ the generic engine
def _crash_on_negative(x: int) -> int:
    if x < 0:
        os._exit(3)  # a worker dying in native code, as far as the pool can tell
    return x * x


def test_pool_imap_bounded_ordered_and_errors() -> None:
    pulled: list[int] = []
    items = ["1", "2", "x", "4", "5", "6", "7", "8"]

    def stream():
        for i, s in enumerate(items):
            pulled.append(i)
            yield s

    with Pool(jobs=2) as pool:
        got = []
        for o in pool.imap(int, stream(), window=3, ordered=True):
            assert len(pulled) - len(got) <= 3  # never more than `window` items taken but not yielded
            got.append(o)
    assert [o.index for o in got] == list(range(8))
    assert [o.value for o in got if o.error is None] == [1, 2, 4, 5, 6, 7, 8]
    assert isinstance(got[2].error, ValueError)


def test_pool_survives_a_crashing_worker() -> None:
    with Pool(jobs=2) as pool:
        got = sorted(pool.imap(_crash_on_negative, [1, 2, -1, 3, 4]), key=lambda o: o.index)
    assert [o.value for o in got if o.error is None] == [1, 4, 9, 16]
    assert isinstance(got[2].error, WorkerCrashed)


def test_load_many_in_order_with_failures(library: Path) -> None:
    (library / "bad.trc").write_text("garbage\n")
    paths = discover(library)
    got = list(load_many(paths, jobs=2))
    assert [p for p, _, _ in got] == paths
    by_name = {p.name: (m, why) for p, m, why in got}
    assert by_name["bad.trc"][0] is None and "not a TRC file" in by_name["bad.trc"][1]
    m = by_name["02_03.bvh"][0]
    assert m is not None and np.array_equal(m.channels, mocapz.load(library / "run" / "02_03.bvh").channels)


def test_folder_without_motion_files_is_an_error(tmp_path: Path) -> None:
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "readme.txt").write_text("nothing here")
    with pytest.raises(MocapzError, match="no motion files"):
        run_batch_compress(tmp_path / "in", tmp_path / "out", "lossless", {}, 1, None, False, False)


def test_several_files_on_worker_processes(library: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    """``mocapz compress A B C -o DIR -j 2``: the files on worker processes, the same bytes as one at a time
    (serially in this process, as without --jobs), a broken one reported by its path and the others written;
    without -o each output goes beside its input."""
    from mocapz.parallel.folder import compress_files

    files = [library / "09_06.bvh", library / "run" / "02_03.bvh", library / "markers" / "Gait.trc"]
    serial = compress_files(files, tmp_path / "serial", "quant", {}, jobs=1)
    pooled = compress_files(files, tmp_path / "pooled", "quant", {}, jobs=2)
    assert not serial.failed and not pooled.failed and serial.mode == "serial" and pooled.mode == "processes"
    assert _outputs(tmp_path / "serial") == _outputs(tmp_path / "pooled")
    assert sorted(_outputs(tmp_path / "pooled")) == ["02_03.bvh.mcz", "09_06.bvh.mcz", "Gait.trc.mcz"]
    assert (tmp_path / "pooled" / "09_06.bvh.mcz").read_bytes() == mocapz.compress(files[0], "quant")
    text = (library / "09_06.bvh").read_text()
    broken = library / "broken.bvh"
    broken.write_text(text[: len(text) // 3])
    from mocapz.cli.batch import run_batch_files
    from mocapz.cli.common import Say

    rc = run_batch_files([files[0], broken], None, "lossless", {}, 2, None, False, False, Say())
    err = capsys.readouterr().err
    assert rc == 1 and f"mocapz: error: {broken}" in err and "1/2 clips compressed, 1 FAILED" in err
    assert (library / "09_06.bvh.mcz").exists() and not (library / "broken.bvh.mcz").exists()


def test_jobs_options_on_files_are_checked(library: Path, tmp_path: Path) -> None:
    """--jobs needs a folder or several files; options a batch cannot honour are refused, not ignored."""
    from click.testing import CliRunner

    from mocapz.cli.main import cli

    runner = CliRunner()
    one = runner.invoke(cli, ["compress", str(library / "09_06.bvh"), "-j", "2"])
    assert isinstance(one.exception, OptionError) and "a folder INPUT or several files" in str(one.exception)
    frames = runner.invoke(cli, ["compress", str(library), "-o", str(tmp_path / "o"), "--frames", "0:10"])
    assert isinstance(frames.exception, OptionError) and "--frames, --start, --end and --unit" in str(frames.exception)
    assert not (tmp_path / "o").exists()
    ok = runner.invoke(cli, ["compress", str(library / "09_06.bvh"), str(library / "run" / "09_01.bvh"), "-o",
                             str(tmp_path / "o"), "-j", "2", "-q"])
    assert ok.exit_code == 0, ok.output
    assert sorted(_outputs(tmp_path / "o")) == ["09_01.bvh.mcz", "09_06.bvh.mcz"]
