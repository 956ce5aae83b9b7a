"""The command line's conventions (zstd's where they fit), run as a real subprocess: default names, several
inputs, folders, standard input and output, --version, case-insensitive codecs, per-codec help, exit codes,
options and existing outputs refused before any input is read, and docs/options.md in step."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path
from test_cli import MOCAPZ, RUN, assert_one_line_error, listing

import mocapz
from mocapz import aot
from mocapz.cli.main import KERNELS
from mocapz.codecs import all_codecs, codec_names
from mocapz.codecs.options import options_markdown
from mocapz.io.bvh import read_bvh

pytestmark = pytest.mark.slow  # subprocesses and a browser: make test, not make test-fast

DOCS = Path(__file__).resolve().parents[1] / "docs" / "options.md"
C3D = "cmu/c3d/01_01.c3d"


def run(*args: object, cwd: Path | None = None, stdin: bytes | None = None) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run([MOCAPZ, *map(str, args)], capture_output=True, timeout=300, cwd=cwd, input=stdin)


def text(res: subprocess.CompletedProcess[bytes]) -> subprocess.CompletedProcess[str]:
    return subprocess.CompletedProcess(res.args, res.returncode, res.stdout.decode(), res.stderr.decode())


@pytest.fixture
def work(tmp_path: Path) -> Path:
    shutil.copyfile(data_path(RUN), tmp_path / "run.bvh")
    shutil.copyfile(data_path("cmu/bvh/02_01.bvh"), tmp_path / "walk.bvh")
    return tmp_path


def test_default_names_both_ways(work: Path) -> None:
    res = run("compress", "run.bvh", cwd=work)
    assert res.returncode == 0 and res.stdout == b"", res.stderr  # messages on stderr only
    assert b"ratio" in res.stderr and b"verified" in res.stderr
    assert listing(work) == ["run.bvh", "run.bvh.mcz", "walk.bvh"]  # the input is kept
    original = (work / "run.bvh").read_bytes()
    (work / "run.bvh").unlink()
    assert run("decompress", "run.bvh.mcz", cwd=work).returncode == 0
    assert np.array_equal(read_bvh(work / "run.bvh").channels, read_bvh(data_path(RUN)).channels)
    assert len(original) > 0


def test_decompress_name_from_the_recorded_format(work: Path) -> None:
    assert run("compress", data_path(C3D), "-o", work / "clip.mcz", "--frames", ":50").returncode == 0
    assert run("decompress", work / "clip.mcz").returncode == 0
    assert (work / "clip.c3d").is_file() and mocapz.load(work / "clip.c3d").n_frames == 50


def test_several_inputs_and_output_folder(work: Path) -> None:
    res = run("compress", "run.bvh", "walk.bvh", "-o", "packed", "--codec", "QUANT", "-q", cwd=work)
    assert res.returncode == 0 and res.stderr == b"", res.stderr  # -q: no messages
    assert listing(work / "packed") == ["run.bvh.mcz", "walk.bvh.mcz"]
    assert mocapz.decompress((work / "packed" / "walk.bvh.mcz").read_bytes()).n_frames == 344
    res = run("decompress", "packed", "-o", "back", cwd=work)  # a folder of .mcz
    assert res.returncode == 0, res.stderr
    assert listing(work / "back") == ["run.bvh", "walk.bvh"]


def test_folder_compress_then_decompress_beside(work: Path) -> None:
    (work / "sub").mkdir()
    shutil.move(work / "walk.bvh", work / "sub" / "walk.bvh")
    res = run("compress", work, "-o", work.parent / "out_folder", "-j", "1")
    assert res.returncode == 0, res.stderr
    assert sorted(p.relative_to(work.parent / "out_folder").as_posix()
                  for p in (work.parent / "out_folder").rglob("*.mcz")) == ["run.bvh.mcz", "sub/walk.bvh.mcz"]


def test_stdin_and_stdout(work: Path) -> None:
    data = (work / "run.bvh").read_bytes()
    res = run("compress", "-", "-c", "--codec", "pga", "--max-error", "3cm", stdin=data)
    assert res.returncode == 0, res.stderr
    assert res.stdout[:4] == b"MCZ\x1a" and b"MCZ" not in res.stderr  # only data on stdout
    back = mocapz.decompress(res.stdout)
    assert mocapz.evaluate(read_bvh(data_path(RUN)), back).max_err_cm <= 3.0
    res = run("decompress", "-", "-o", "-", "--format", "bvh", stdin=res.stdout)
    assert res.returncode == 0 and res.stdout.startswith(b"HIERARCHY"), res.stderr
    res = run("compress", "-", "-o", work / "c3d.mcz", stdin=data_path(C3D).read_bytes())  # C3D sniffed
    assert res.returncode == 0, res.stderr
    assert mocapz.decompress((work / "c3d.mcz").read_bytes()).source_format == "c3d"


def test_stdin_garbage_is_a_clean_error(work: Path) -> None:
    res = text(run("compress", "-", "-o", work / "x.mcz", stdin=b"hello world\n" * 10))
    assert_one_line_error(res, "<stdin>")
    assert not (work / "x.mcz").exists()


def test_version_and_help() -> None:
    res = text(run("-V"))
    assert res.returncode == 0 and mocapz.__version__ in res.stdout
    assert f"kernels: {KERNELS[aot.in_use()]}" in res.stdout  # which compiled kernels the commands use
    res = text(run("compress", "--help"))
    assert res.returncode == 0
    for name in codec_names():
        assert name in res.stdout
    assert "--max-error" in res.stdout and "--geodesics" not in res.stdout
    res = text(run("compress", "--codec", "PGA", "--help"))
    assert "--geodesics" in res.stdout and "--theta" not in res.stdout
    res = text(run("compress", "--codec", "patterns", "--help"))
    assert "--theta" in res.stdout and "--geodesics" not in res.stdout


def test_bad_option_and_existing_output_fail_before_reading(tmp_path: Path) -> None:
    """A 4,906-frame clip: refused in well under the time reading it would take, with exit code 2 / 1."""
    big = data_path("cmu/bvh/06_13.bvh")
    res = text(run("compress", big, "-o", tmp_path / "x.mcz", "--codec", "pga", "--lod-root", "-1"))
    assert_one_line_error(res, "--lod-root", code=2)
    (tmp_path / "x.mcz").write_bytes(b"keep")
    res = text(run("compress", big, "-o", tmp_path / "x.mcz", "--codec", "pga", "--max-error", "1cm"))
    assert_one_line_error(res, "x.mcz")
    assert (tmp_path / "x.mcz").read_bytes() == b"keep"
    folder = tmp_path / "lib"
    folder.mkdir()
    shutil.copyfile(data_path(RUN), folder / "a.bvh")
    res = text(run("compress", folder, "--codec", "pga", "--bogus-length", "1"))
    assert res.returncode == 2  # click refuses the unknown flag


def test_frames_range_on_compress_and_eval(work: Path) -> None:
    assert run("compress", "run.bvh", "-o", "part.mcz", "--frames", "10:60", cwd=work).returncode == 0
    assert mocapz.decompress((work / "part.mcz").read_bytes()).n_frames == 50
    res = run("eval", "run.bvh", "part.mcz", "--frames", "10:60", "--json", cwd=work)
    assert res.returncode == 0, res.stderr
    assert b'"max_err": 0.0' in res.stdout
    res = text(run("compress", "run.bvh", "-o", "none.mcz", "--frames", "90:20", cwd=work))
    assert_one_line_error(res, "frame range", code=2)


def test_unit_flag_makes_a_length_target_possible(work: Path) -> None:
    """A skeleton whose unit is unknown takes --max-error 2cm once --unit says what the numbers are."""
    sk_text = (work / "run.bvh").read_text().replace("Hips", "Pelvis")  # no CMU names: unit guessed, not known
    (work / "odd.bvh").write_text(sk_text)
    res = run("compress", "odd.bvh", "-o", "u.mcz", "--codec", "quant", "--max-error", "2cm", "--unit", "cmu",
              cwd=work)
    assert res.returncode == 0, res.stderr
    assert mocapz.decompress((work / "u.mcz").read_bytes()).skeleton.unit_cm == pytest.approx(2.54 / 0.45)


def test_options_doc_is_in_step() -> None:
    assert DOCS.read_text() == options_markdown(all_codecs()), "regenerate: python -m mocapz.codecs > docs/options.md"


def test_codec_that_does_not_take_the_data_is_a_file_error(tmp_path: Path) -> None:
    """Options are fine (checked before reading); the file is what the codec cannot take: exit code 1."""
    res = text(run("compress", data_path(C3D), "-o", tmp_path / "x.mcz", "--codec", "pga"))
    assert_one_line_error(res, "01_01.c3d")
    assert "markers" in res.stderr and not (tmp_path / "x.mcz").exists()
