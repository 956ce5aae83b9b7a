"""``mocapz compress DIR -o OUTDIR``: the command-line side of batch compression (see :mod:`mocapz.parallel.folder`).

``mocapz compress`` calls :func:`run_batch_compress` when its INPUT is a folder, :func:`run_batch_files` for
several files with ``--jobs`` or ``--scheduler``. Output: one line per
failed clip on stderr (``mocapz: error: PATH: reason``), then a summary line on stderr (or one JSON object
on stdout with ``--json``); exit code 1 if any clip failed, else 0. Existing outputs are found before any
clip is read.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click

from mocapz.cli.common import Say
from mocapz.cli.outputs import check_outputs
from mocapz.codecs import get_codec
from mocapz.errors import MocapzError
from mocapz.format.extras_precision import ExtrasPrecision
from mocapz.parallel.discover import BATCH_EXTENSIONS, discover, plan
from mocapz.parallel.folder import compress_files, compress_folder
from mocapz.parallel.report import BatchReport


def _absolute_paths(codec: str, options: dict[str, Any]) -> dict[str, Any]:
    """Options naming files (declared kind ``file`` or ``weights``) made absolute, so that workers whose
    working folder differs (Dask) find them."""
    out = dict(options)
    for o in get_codec(codec).options:
        v = out.get(o.name)
        if o.kind in ("file", "weights") and isinstance(v, str) and v and Path(v).exists():
            out[o.name] = str(Path(v).resolve())
    return out


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if abs(n) < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} GB"  # pragma: no cover


def summary_line(report: BatchReport, input_dir: Path | str, output_dir: Path | str) -> str:
    """One line describing a finished batch."""
    n = len(report.results)
    failed = len(report.failed)
    comp = report.compressed_bytes
    ratio = f", ratio {report.raw_bytes / comp:.3g} (file ratio {report.input_bytes / comp:.3g})" if comp else ""
    status = f"{n - failed}/{n} clips compressed" + (f", {failed} FAILED" if failed else "")
    return (f"{input_dir} -> {output_dir}: {status}; {report.frames:,} frames, {_size(report.input_bytes)} -> "
            f"{_size(comp)}{ratio}; {report.codec}, {report.description}, {report.seconds:.2f} s, "
            f"{report.frames_per_second:,.0f} frames/s, {report.clips_per_second:.2f} clips/s")


def run_batch_files(paths: list[Path], output_dir: Path | None, codec: str, options: dict[str, Any],
                    jobs: int | None, scheduler: str | None, force: bool, as_json: bool, say: Say,
                    block: str | None = None, precision: ExtrasPrecision | None = None) -> int:
    """``mocapz compress FILES... [-o OUTDIR] -j N``: the files on worker processes (or Dask), as a folder's
    (:func:`run_batch_compress`: the same messages and exit code); the outputs were checked by the caller."""
    report = compress_files(list(paths), output_dir, codec, _absolute_paths(codec, options), jobs=jobs,
                            scheduler=scheduler, force=force, progress=not (as_json or say.quiet), block=block,
                            precision=precision)
    where = f"{len(paths)} files"
    return _report(report, Path("."), where, str(output_dir) if output_dir is not None else "beside them",
                   as_json, say)


def run_batch_compress(input_dir: Path, output_dir: Path, codec: str, options: dict[str, Any], jobs: int | None,
                       scheduler: str | None, force: bool, as_json: bool, say: Say | None = None,
                       block: str | None = None, precision: ExtrasPrecision | None = None) -> int:
    """Compress every clip under ``input_dir`` into ``output_dir``; return the exit code (0, or 1 if any failed).

    Args:
        input_dir: folder searched recursively for ``.bvh``, ``.amc``, ``.c3d`` and ``.trc`` files.
        output_dir: where the ``.mcz`` files go, mirroring the input layout (created if missing).
        codec, options: codec name and its checked options, as for one file.
        jobs: worker processes (``None``: one per CPU, ``1``: serial); with ``scheduler="local"`` the
            number of Dask workers.
        scheduler: Dask scheduler address, ``"local"`` for a LocalCluster on 127.0.0.1, or ``None``.
        force: overwrite existing outputs (otherwise those clips fail with "output exists").
        as_json: print one JSON object (totals, failures, per-clip results) instead of the summary line.
        say: messages (``-q`` / ``-v``).
        block: the block length (``--block``); precision: ``--analog-precision`` / ``--track-precision``.

    Errors about the whole batch (no such folder, no motion file in it, unknown codec, unreachable
    scheduler) are raised as :class:`~mocapz.errors.MocapzError` for the CLI's usual one-line report.
    """
    say = say or Say()
    if not discover(input_dir):
        raise MocapzError(f"{input_dir}: no motion files ({', '.join(BATCH_EXTENSIONS)}) in this folder")
    check_outputs([Path(j.output) for j in plan(input_dir, output_dir)], force, folders_made=True)
    report = compress_folder(input_dir, output_dir, codec, _absolute_paths(codec, options), jobs=jobs,
                             scheduler=scheduler, force=force, progress=not (as_json or say.quiet), block=block,
                             precision=precision)
    return _report(report, Path(input_dir), str(input_dir), str(output_dir), as_json, say)


def _report(report: BatchReport, root: Path, inputs: str, outputs: str, as_json: bool, say: Say) -> int:
    """One line per failed clip (its path under ``root``), then the summary line (or the JSON object); the exit
    code."""
    for r in report.failed:
        click.echo(f"mocapz: error: {root / r.name}: {r.error}", err=True)
    if as_json:
        d = report.as_dict()
        d.update(input=inputs, output=outputs)
        click.echo(json.dumps(d))
    else:
        say.info(summary_line(report, inputs, outputs))
    sys.stderr.flush()
    return 1 if report.failed else 0
