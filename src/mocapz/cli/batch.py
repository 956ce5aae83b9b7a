"""``mocapz compress DIR -o OUTDIR``: the command-line side of batch compression (see :mod:`mocapz.parallel.folder`).

``mocapz compress`` calls :func:`run_batch_compress` when its INPUT is a folder. Output: one line per
failed clip on stderr (``mocapz: error: PATH: reason``), then a summary line on stdout (or one JSON object
with ``--json``); exit code 1 if any clip failed, else 0.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click

from mocapz.errors import MocapzError
from mocapz.parallel.discover import BATCH_EXTENSIONS, discover
from mocapz.parallel.folder import compress_folder
from mocapz.parallel.report import BatchReport

# Codec options naming files: made absolute, so workers whose working folder differs (Dask) find them.
_PATH_OPTIONS = ("hierarchy", "weights")


def _absolute_paths(options: dict[str, Any]) -> dict[str, Any]:
    out = dict(options)
    for key in _PATH_OPTIONS:
        v = out.get(key)
        if isinstance(v, str) and v and Path(v).exists():
            out[key] = str(Path(v).resolve())
    return out


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if abs(n) < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} GB"  # pragma: no cover


def summary_line(report: BatchReport, input_dir: Path, output_dir: Path) -> str:
    """One line describing a finished batch."""
    n = len(report.results)
    failed = len(report.failed)
    comp = report.compressed_bytes
    ratio = f", ratio {report.raw_bytes / comp:.3g} (file ratio {report.input_bytes / comp:.3g})" if comp else ""
    status = f"{n - failed}/{n} clips compressed" + (f", {failed} FAILED" if failed else "")
    return (f"{input_dir} -> {output_dir}: {status}; {report.frames:,} frames, {_size(report.input_bytes)} -> "
            f"{_size(comp)}{ratio}; {report.codec}, {report.description}, {report.seconds:.2f} s, "
            f"{report.frames_per_second:,.0f} frames/s, {report.clips_per_second:.2f} clips/s")


def run_batch_compress(input_dir: Path, output_dir: Path, codec: str, options: dict[str, Any], jobs: int | None,
                       scheduler: str | None, force: bool, as_json: bool) -> int:
    """Compress every clip under ``input_dir`` into ``output_dir``; return the exit code (0, or 1 if any failed).

    Args:
        input_dir: folder searched recursively for ``.bvh``, ``.amc``, ``.c3d`` and ``.trc`` files.
        output_dir: where the ``.mcz`` files go, mirroring the input layout (created if missing).
        codec, options: codec name and its options (only those given), as for one file.
        jobs: worker processes (``None``: one per CPU, ``1``: serial); with ``scheduler="local"`` the
            number of Dask workers.
        scheduler: Dask scheduler address, ``"local"`` for a LocalCluster on 127.0.0.1, or ``None``.
        force: overwrite existing outputs (otherwise those clips fail with "output exists").
        as_json: print one JSON object (totals, failures, per-clip results) instead of the summary line.

    Errors about the whole batch (no such folder, no motion file in it, unknown codec, unreachable
    scheduler) are raised as :class:`~mocapz.errors.MocapzError` for the CLI's usual one-line report.
    """
    if not discover(input_dir):
        raise MocapzError(f"{input_dir}: no motion files ({', '.join(BATCH_EXTENSIONS)}) in this folder")
    report = compress_folder(input_dir, output_dir, codec, _absolute_paths(options), jobs=jobs, scheduler=scheduler,
                             force=force, progress=not as_json)
    root = Path(input_dir)
    for r in report.failed:
        click.echo(f"mocapz: error: {root / r.name}: {r.error}", err=True)
    if as_json:
        d = report.as_dict()
        d.update(input=str(input_dir), output=str(output_dir))
        click.echo(json.dumps(d))
    else:
        click.echo(summary_line(report, Path(input_dir), Path(output_dir)))
    sys.stderr.flush()
    return 1 if report.failed else 0
