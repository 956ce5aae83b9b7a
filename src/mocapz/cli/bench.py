"""``mocapz bench``: measure every codec side by side on the same clips (see :mod:`mocapz.bench`)."""

from __future__ import annotations

import shlex
import sys
import time
from pathlib import Path

import click


@click.command(name="bench")
@click.argument("paths", nargs=-1, type=click.Path(path_type=Path))
@click.option("--codecs", default=None,
              help="comma-separated codecs (default: lossless, pga, patterns, quant, subsample, pca, segpca, "
                   "gzip, bzip2, xz, zstd); lossless is always measured as the speed reference")
@click.option("--quick", is_flag=True, help="short sweeps; from the default corpus only a handful of short clips")
@click.option("-o", "--output", "out_dir", type=click.Path(path_type=Path), required=True,
              help="report folder (results.json, report.md, PNG plots; existing ones are replaced)")
@click.option("--no-plots", is_flag=True, help="skip the PNG plots")
@click.option("--timeout", type=float, default=900.0, show_default=True,
              help="seconds allowed per codec call; a slower call is recorded as a failure")
@click.option("-q", "--quiet", "--no-progress", "no_progress", is_flag=True, help="no progress bar")
def bench(paths: tuple[Path, ...], codecs: str | None, quick: bool, out_dir: Path, no_plots: bool,
          timeout: float, no_progress: bool) -> None:
    """Compress, decompress and score every clip with every codec at a sweep of settings.

    PATHS are motion files or folders (searched recursively); default: the CMU clips of ../shared/data
    (or $MOCAPZ_DATA/cmu). A codec that fails on a clip is recorded with its message; the run goes on.
    """
    from mocapz.bench import run_bench, write_report
    from mocapz.bench.sweeps import parse_codecs

    names = parse_codecs(codecs)  # reject unknown names before any work
    command = "mocapz " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:2] == ["bench"] else None
    t0 = time.perf_counter()
    doc = run_bench(list(paths) or None, names, quick=quick, timeout=timeout if timeout > 0 else None,
                    progress=not no_progress, command=command or _command(paths, codecs, quick, out_dir))
    written = write_report(doc, out_dir, plots=not no_plots)
    ok = sum(r.get("status") == "ok" for r in doc["records"])
    failed = len(doc["records"]) - ok
    if not no_progress:
        click.echo(f"{len(doc['clips'])} clips, {ok} measurements, {failed} failures in "
                   f"{time.perf_counter() - t0:.0f} s -> {written['report']}", err=True)


def _command(paths: tuple[Path, ...], codecs: str | None, quick: bool, out_dir: Path) -> str:
    parts = ["mocapz", "bench", *(str(p) for p in paths)]
    if codecs:
        parts += ["--codecs", codecs]
    if quick:
        parts.append("--quick")
    parts += ["-o", str(out_dir)]
    return " ".join(shlex.quote(p) for p in parts)
