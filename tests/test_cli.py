"""The ``mocapz`` command line, run as a real subprocess: bad inputs, overwriting, usage errors, --json output
and a compress / decompress / eval round trip.

``cli.py`` has no ``if __name__ == "__main__"`` block, so ``python -m mocapz.cli.main`` would do nothing: the tests
run the installed console script that sits beside the interpreter.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.io.bvh import read_bvh

MOCAPZ = shutil.which("mocapz", path=str(Path(sys.executable).parent)) or str(Path(sys.executable).parent / "mocapz")
RUN = "cmu/bvh/09_06.bvh"


def mocapz_cli(*args: object, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """Run the ``mocapz`` command with ``args`` and capture its output."""
    return subprocess.run([MOCAPZ, *map(str, args)], capture_output=True, text=True, timeout=120, cwd=cwd)


def listing(folder: Path) -> list[str]:
    """Every file name in ``folder`` (hidden temporary files included), sorted."""
    return sorted(p.name for p in folder.iterdir())


def assert_one_line_error(res: subprocess.CompletedProcess[str], names: str, code: int = 1) -> str:
    """Exit code ``code`` (1: a file failed, 2: usage), exactly one line on stderr that names ``names``, no
    traceback. Returns the line."""
    assert res.returncode == code, (res.returncode, res.stdout, res.stderr)
    lines = res.stderr.splitlines()
    assert len(lines) == 1, res.stderr
    assert "Traceback" not in res.stderr and "internal error" not in res.stderr, res.stderr
    assert names in lines[0], lines[0]
    return lines[0]


@pytest.fixture(scope="module")
def mcz(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A lossless .mcz of the first 20 frames of 09_06 (written through the API)."""
    p = tmp_path_factory.mktemp("mcz") / "short.mcz"
    p.write_bytes(mocapz.compress(read_bvh(data_path(RUN)).slice(0, 20), codec="lossless"))
    return p


@pytest.fixture
def dirs(tmp_path: Path) -> tuple[Path, Path]:
    """An input folder and an empty output folder."""
    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    return tmp_path / "in", tmp_path / "out"


# ------------------------------------------------------------------------------------ bad inputs
def _bvh_lines() -> tuple[list[str], int]:
    """Lines of 09_06.bvh and the index of its MOTION line."""
    lines = data_path(RUN).read_text().splitlines()
    return lines, [ln.strip() for ln in lines].index("MOTION")


def _make_bad_input(kind: str, folder: Path) -> tuple[Path, list[str]]:
    """Write a bad input file of the given kind; return it and the extra command-line arguments."""
    lines, motion = _bvh_lines()
    if kind == "empty":
        p = folder / "empty.bvh"
        p.write_text("")
    elif kind == "truncated":
        p = folder / "truncated.bvh"
        cut = motion + 3 + 40  # in the middle of the MOTION rows, half-way through a row
        p.write_text("\n".join(lines[:cut]) + "\n" + lines[cut][: len(lines[cut]) // 2])
    elif kind == "channel-count":
        p = folder / "count.bvh"
        lines[motion + 10] += " 0.5"
        p.write_text("\n".join(lines) + "\n")
    elif kind == "nan":
        p = folder / "nan.bvh"
        row = lines[motion + 10].split()
        row[7] = "nan"
        lines[motion + 10] = " ".join(row)
        p.write_text("\n".join(lines) + "\n")
    elif kind == "amc-unknown-joint":
        p = folder / "bogus.amc"
        amc = data_path("cmu/asfamc/01_01.amc").read_text().splitlines()[:64]  # header and two frames
        amc[40] = "bogusbone 1.0 2.0 3.0"
        p.write_text("\n".join(amc) + "\n")
        return p, ["--asf", str(data_path("cmu/asfamc/01.asf"))]
    elif kind == "missing":
        p = folder / "missing.bvh"
    elif kind == "unknown-extension":
        p = folder / "motion.txt"
        p.write_text("hello\n")
    else:
        raise AssertionError(kind)
    return p, []


# what the one error line must also say, beyond the file name (":<line>:" is the 1-based line in the file)
BAD_INPUTS = {
    "empty": "empty",
    "truncated": "truncated",
    "channel-count": "97 values",
    "nan": "NaN",
    "amc-unknown-joint": "'bogusbone' is not in the ASF",
    "missing": "no such file",
    "unknown-extension": "extension",
}


@pytest.mark.parametrize("kind", list(BAD_INPUTS))
def test_compress_bad_input(kind: str, dirs: tuple[Path, Path]) -> None:
    src, out = dirs
    path, extra = _make_bad_input(kind, src)
    before = listing(src)
    res = mocapz_cli("compress", path, "-o", out / "x.mcz", *extra)
    line = assert_one_line_error(res, str(path))
    assert BAD_INPUTS[kind] in line
    if kind in ("channel-count", "nan"):
        assert f"{path}:{_bvh_lines()[1] + 11}:" in line  # the bad row's line number
    assert listing(out) == [] and listing(src) == before
    assert res.stdout == ""


@pytest.mark.parametrize("kind", ["garbage", "truncated", "missing", "folder"])
def test_decompress_bad_mcz(kind: str, dirs: tuple[Path, Path], mcz: Path) -> None:
    src, out = dirs
    path = src / f"{kind}.mcz"
    if kind == "garbage":
        path.write_bytes(b"this is not a mocapz file\n" * 20)
    elif kind == "truncated":
        data = mcz.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    elif kind == "folder":
        path.mkdir()
    res = mocapz_cli("decompress", path, "-o", out / "x.bvh")
    assert_one_line_error(res, path.name)
    assert listing(out) == []


def test_decompress_wrong_output_extension(dirs: tuple[Path, Path], mcz: Path) -> None:
    _, out = dirs
    res = mocapz_cli("decompress", mcz, "-o", out / "x.xyz")
    assert_one_line_error(res, "x.xyz", code=2)
    assert listing(out) == []


def test_decompress_skeleton_to_marker_format(dirs: tuple[Path, Path], mcz: Path) -> None:
    _, out = dirs
    assert_one_line_error(mocapz_cli("decompress", mcz, "-o", out / "x.trc"), "x.trc")
    assert listing(out) == []


def test_decompress_into_missing_folder(dirs: tuple[Path, Path], mcz: Path) -> None:
    _, out = dirs
    assert_one_line_error(mocapz_cli("decompress", mcz, "-o", out / "nope" / "x.bvh"), "x.bvh")
    assert listing(out) == []


def test_info_and_eval_bad_input(dirs: tuple[Path, Path]) -> None:
    src, _ = dirs
    junk = src / "junk.mcz"
    junk.write_bytes(b"\x00" * 100)
    assert_one_line_error(mocapz_cli("info", junk), "junk.mcz")
    assert_one_line_error(mocapz_cli("eval", data_path(RUN), src / "nothing.bvh"), "nothing.bvh")


@pytest.mark.parametrize(("args", "named"), [(["--codec", "nosuch"], "nosuch"), (["--bits", "8"], "--bits"),
                                             (["--codec", "PGA", "--geodesics", "0"], "--geodesics"),
                                             (["--codec", "patterns", "--max-error", "2 parsecs"], "--max-error")],
                         ids=["unknown-codec", "option-of-another-codec", "out-of-range", "bad-length"])
def test_compress_bad_options(args: list[str], named: str, dirs: tuple[Path, Path]) -> None:
    _, out = dirs
    res = mocapz_cli("compress", data_path(RUN), "-o", out / "x.mcz", *args)
    assert_one_line_error(res, named, code=2)
    assert listing(out) == []


# ---------------------------------------------------------------------------------- usage errors
@pytest.mark.parametrize("args", [["compress"], ["eval", "a.bvh"], ["frobnicate"], ["compress", "x.bvh", "--bogus"]],
                         ids=["no-input", "one-file", "unknown-command", "unknown-flag"])
def test_usage_errors_exit_2(args: list[str], tmp_path: Path) -> None:
    res = mocapz_cli(*args, cwd=tmp_path)
    assert res.returncode == 2, res.stderr
    assert "Usage" in res.stderr and "Traceback" not in res.stderr
    assert listing(tmp_path) == []


# ---------------------------------------------------------------------------------- overwriting
def test_compress_does_not_overwrite_without_force(dirs: tuple[Path, Path]) -> None:
    _, out = dirs
    target = out / "x.mcz"
    target.write_bytes(b"precious")
    res = mocapz_cli("compress", data_path(RUN), "-o", target)
    assert_one_line_error(res, "x.mcz")
    assert target.read_bytes() == b"precious" and listing(out) == ["x.mcz"]
    res = mocapz_cli("compress", data_path(RUN), "-o", target, "-f")
    assert res.returncode == 0, res.stderr
    assert target.read_bytes()[:4] == b"MCZ\x1a" and listing(out) == ["x.mcz"]


def test_decompress_does_not_overwrite_without_force(dirs: tuple[Path, Path], mcz: Path) -> None:
    _, out = dirs
    target = out / "x.bvh"
    target.write_text("precious")
    assert_one_line_error(mocapz_cli("decompress", mcz, "-o", target), "x.bvh")
    assert target.read_text() == "precious" and listing(out) == ["x.bvh"]
    assert mocapz_cli("decompress", mcz, "-o", target, "--force").returncode == 0
    assert np.array_equal(read_bvh(target).channels, read_bvh(data_path(RUN)).channels[:20])


def test_decompress_amc_keeps_a_different_asf(dirs: tuple[Path, Path], mcz: Path) -> None:
    """An existing, different skeleton file beside the .amc output is not replaced without -f."""
    _, out = dirs
    (out / "x.asf").write_text("precious")
    assert_one_line_error(mocapz_cli("decompress", mcz, "-o", out / "x.amc"), "x.asf")
    assert (out / "x.asf").read_text() == "precious" and listing(out) == ["x.asf"]


# -------------------------------------------------------------------------------- round trip, json
@pytest.fixture(scope="module")
def round_trip(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """compress --json, then decompress --json to .bvh and to .amc, of the whole 09_06 clip."""
    out = tmp_path_factory.mktemp("rt")
    res: dict[str, object] = {"dir": out}
    for key, args in {
        "compress": ["compress", data_path(RUN), "-o", out / "run.mcz", "--codec", "lossless", "--json"],
        "decompress": ["decompress", out / "run.mcz", "-o", out / "run.bvh", "--json"],
        "amc": ["decompress", out / "run.mcz", "-o", out / "run.amc", "--json"],
    }.items():
        r = mocapz_cli(*args)
        assert r.returncode == 0, r.stderr
        res[key] = r
    return res


def _json(res: subprocess.CompletedProcess[str]) -> dict[str, object]:
    """The single JSON object a --json command printed."""
    assert res.returncode == 0, res.stderr
    assert len(res.stdout.strip().splitlines()) == 1, res.stdout
    obj = json.loads(res.stdout)
    assert isinstance(obj, dict)
    return obj


def test_compress_json(round_trip: dict[str, object]) -> None:
    d = _json(round_trip["compress"])  # type: ignore[arg-type]
    out: Path = round_trip["dir"]  # type: ignore[assignment]
    size = (out / "run.mcz").stat().st_size
    assert d["compressed_bytes"] == size and d["raw_bytes"] == 142 * 96 * 4 and d["frames"] == 142
    assert d["ratio"] == pytest.approx(d["raw_bytes"] / size) and d["codec"] == "lossless"
    assert d["ratio_file"] == pytest.approx(data_path(RUN).stat().st_size / size)


def test_decompress_json_and_files(round_trip: dict[str, object]) -> None:
    out: Path = round_trip["dir"]  # type: ignore[assignment]
    d = _json(round_trip["decompress"])  # type: ignore[arg-type]
    assert d["outputs"] == [str(out / "run.bvh")] and d["frames"] == 142
    orig, back = read_bvh(data_path(RUN)), read_bvh(out / "run.bvh")
    assert np.array_equal(back.channels, orig.channels) and np.array_equal(back.skeleton.offsets, orig.skeleton.offsets)
    assert not [n for n in listing(out) if n.startswith(".")]  # no temporary files left


def test_decompress_amc_writes_asf(round_trip: dict[str, object]) -> None:
    out: Path = round_trip["dir"]  # type: ignore[assignment]
    d = _json(round_trip["amc"])  # type: ignore[arg-type]
    assert d["outputs"] == [str(out / "run.amc"), str(out / "run.asf")]
    assert (out / "run.asf").is_file() and (out / "run.amc").is_file()
    amc = mocapz.load(out / "run.amc")
    assert amc.n_frames == 142
    # the same points, in the same order here, at the same places
    assert np.allclose(amc.positions(), read_bvh(data_path(RUN)).positions(), rtol=0, atol=1e-9)


def test_eval_json_decoded_bvh_is_exact(round_trip: dict[str, object]) -> None:
    out: Path = round_trip["dir"]  # type: ignore[assignment]
    d = _json(mocapz_cli("eval", data_path(RUN), out / "run.bvh", "--json"))
    assert d["distortion_pct"] == 0.0 and d["max_err"] == 0.0 and d["arms"] == 0.0 and d["bone_len_err"] == 0.0
    assert d["frames"] == 142 and d["points"] == 38


def test_eval_json_on_mcz_has_sizes(round_trip: dict[str, object]) -> None:
    out: Path = round_trip["dir"]  # type: ignore[assignment]
    d = _json(mocapz_cli("eval", data_path(RUN), out / "run.mcz", "--json"))
    assert d["distortion_pct"] == 0.0 and d["p99_err"] == 0.0
    assert d["compressed_bytes"] == (out / "run.mcz").stat().st_size
    assert d["ratio"] == pytest.approx(142 * 96 * 4 / d["compressed_bytes"])


def test_eval_decoded_amc_against_bvh(round_trip: dict[str, object]) -> None:
    """Lossless data decoded to .amc is the same motion: eval must say so (or refuse), not report an error.

    The AMC's channel columns are ordered as its ASF dofs (rx ry rz), not as the BVH's (Z Y X).
    """
    out: Path = round_trip["dir"]  # type: ignore[assignment]
    res = mocapz_cli("eval", data_path(RUN), out / "run.amc", "--json")
    if res.returncode == 1:  # refusing to compare different channel layouts is acceptable
        assert_one_line_error(res, "run.amc")
        return
    d = _json(res)
    assert d["distortion_pct"] < 1e-9 and d["max_err"] < 1e-9, d


def test_eval_plain_text(round_trip: dict[str, object]) -> None:
    out: Path = round_trip["dir"]  # type: ignore[assignment]
    res = mocapz_cli("eval", data_path(RUN), out / "run.mcz")
    assert res.returncode == 0 and res.stderr == ""
    assert "distortion_pct" in res.stdout and "ratio" in res.stdout


@pytest.mark.parametrize("target", ["mcz", "bvh"])
def test_info_json(target: str, round_trip: dict[str, object]) -> None:
    out: Path = round_trip["dir"]  # type: ignore[assignment]
    path = out / "run.mcz" if target == "mcz" else data_path(RUN)
    d = _json(mocapz_cli("info", path, "--json"))
    assert d["frames"] == 142 and d["joints"] == 31 and d["channels"] == 96 and d["frame_rate"] == 120.0
    if target == "mcz":
        assert d["codec"] == "lossless" and d["container_bytes"] == path.stat().st_size
        assert d["ratio"] == pytest.approx(142 * 96 * 4 / path.stat().st_size)
    else:
        assert d["file_bytes"] == path.stat().st_size
