"""``mocapz compress INPUT... [-o OUTPUT] [--codec NAME] [codec options]``.

* one file: ``clip.bvh`` -> ``clip.bvh.mcz`` beside it, or ``-o`` names the output (``-o -`` / ``-c``:
  standard output); ``-`` as INPUT reads standard input (format sniffed, or ``--format``);
* several files or folders: each to its default name, or under the folder ``-o`` names; a folder is
  compressed clip by clip in parallel (:mod:`mocapz.cli.batch`).

Options are checked and existing outputs found before any input is read. After compressing, the result is
decoded and measured: the line printed (stderr) gives the verified figures and both ratios.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import click

from mocapz.cli.codec_flags import CodecCommand, check_codec_options, codec_flags
from mocapz.cli.common import (
    Say,
    cut,
    each_input,
    finish,
    fmt,
    frame_slice,
    message_flags,
    range_flags,
    unit_flag,
    with_unit,
)
from mocapz.cli.outputs import check_outputs, write_output
from mocapz.codecs.target import DEFAULT_TARGET, TARGET_NAMES
from mocapz.errors import MocapzError, OptionError
from mocapz.files import STDIN_NAME, compressed_name, load_bytes, sniff
from mocapz.format.container import Container
from mocapz.format.extras import PREFIX as EXTRAS_PREFIX
from mocapz.format.extras_precision import ExtrasPrecision
from mocapz.io import MOTION_EXTENSIONS

FORMATS = tuple(e.lstrip(".") for e in MOTION_EXTENSIONS)


@click.command(cls=CodecCommand)
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path, allow_dash=True))
@click.option("-o", "--output", type=click.Path(path_type=Path, allow_dash=True), default=None,
              help="output .mcz (one input; - for stdout), or output folder (several inputs or a folder)")
@click.option("-c", "--stdout", "to_stdout", is_flag=True, help="write the .mcz to standard output")
@click.option("--codec", default="lossless", show_default=True, help="codec name, any case (list below)")
@click.option("--format", "fmt_name", type=click.Choice(FORMATS, case_sensitive=False), default=None,
              help="format of standard input (default: from its content)")
@click.option("--asf", type=click.Path(path_type=Path), default=None, help="skeleton for an .amc input")
@click.option("-f", "--force", is_flag=True, help="overwrite existing outputs")
@click.option("--json", "as_json", is_flag=True, help="print one JSON object on stdout")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=None,
              help="a folder INPUT (default: one per CPU) or several files (default: one at a time, each "
                   "verified on its own line): worker processes (1: serial)")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="a folder or several files: a Dask cluster (tcp://host:8786), or 'local' (needs mocapz[dask])")
@click.option("--block", default=None, metavar="LENGTH",
              help="code the clip in independent blocks of LENGTH (4s, 240 frames; 0: one block), so that "
                   "decompress --frames decodes only the blocks it needs (default: the codec's)")
@click.option("--analog-precision", "analog_precision", multiple=True, metavar="[LABEL=]ERROR",
              help="C3D analog channels within ERROR in their own units (all, or the channel LABEL; "
                   "repeatable); default: bit for bit")
@click.option("--track-precision", "track_precision", multiple=True, metavar="[NAME=]ERROR",
              help="C3D model outputs (angles, forces, moments, powers) within ERROR in their own units: all, "
                   "a kind (angles=0.01) or a label; repeatable; default: bit for bit")
@range_flags
@unit_flag
@message_flags
@codec_flags()
def compress(inputs: tuple[Path, ...], output: Path | None, to_stdout: bool, codec: str, fmt_name: str | None,
             asf: Path | None, force: bool, as_json: bool, jobs: int | None, scheduler: str | None,
             block: str | None, analog_precision: tuple[str, ...], track_precision: tuple[str, ...],
             frames: str | None, start: float | None, end: float | None, unit: str | None,
             quiet: bool, verbose: bool, **params: Any) -> None:
    """Compress motion files (.bvh, .amc, .c3d, .trc) or folders of them into .mcz files."""
    from mocapz.blocking import block_frames

    info, options = check_codec_options(codec, params)
    block_frames(block, 1.0, 0.0)  # a bad --block fails before any input is read
    precision = ExtrasPrecision.of(analog_precision or None, track_precision or None)
    say = Say(quiet, verbose)
    if to_stdout:
        if output is not None and str(output) != "-":
            raise OptionError("give -c or -o, not both")
        output = Path("-")
    folders = [p for p in inputs if str(p) != "-" and p.is_dir()]
    files = [p for p in inputs if p not in folders]
    pooled = jobs is not None or scheduler is not None  # the files too go to worker processes (or Dask)
    if pooled and not folders and len(files) < 2:
        raise OptionError("--jobs and --scheduler apply to a folder INPUT or several files")
    if pooled and any(str(p) == "-" for p in files):
        raise OptionError("--jobs and --scheduler take files and folders, not standard input (-)")
    if (folders or pooled) and (frames is not None or start is not None or end is not None or unit is not None):
        raise OptionError("--frames, --start, --end and --unit apply to files compressed one at a time (not to a "
                          "folder INPUT or with --jobs / --scheduler)")
    if asf is not None and (len(inputs) > 1 or folders):
        raise OptionError("--asf applies to one .amc file; in a folder each .amc uses the .asf beside it")
    many = len(inputs) > 1 or bool(folders)
    if many and output is not None and str(output) == "-":
        raise OptionError("standard output takes one input, not several or a folder")
    if sum(str(p) == "-" for p in inputs) > 1:
        raise OptionError("standard input (-) can be read once")
    targets = [_output_for(p, output, many) for p in inputs if p not in folders]
    check_outputs(targets, force, folders_made=many and output is not None)
    if many and output is not None:
        output.mkdir(parents=True, exist_ok=True)
    failed = 0
    for path in folders:
        from mocapz.cli.batch import run_batch_compress

        out_dir = output / path.name if (output is not None and len(inputs) > 1) else (output or path)
        failed += run_batch_compress(path, out_dir, info.name, options, jobs, scheduler, force, as_json, say, block,
                                     precision)
    if pooled and files:
        from mocapz.cli.batch import run_batch_files

        failed += run_batch_files(files, output if many else None, info.name, options, jobs, scheduler, force,
                                  as_json, say, block, precision)
        files = []
    results, bad = each_input(files, lambda p: _one(p, _output_for(p, output, many), info.name, options, block,
                                                    asf, fmt_name, (frames, start, end), unit, force, say,
                                                    precision), many)
    finish(results, many, as_json, failed + bad)


def _output_for(path: Path, output: Path | None, many: bool) -> Path:
    if str(path) == "-":
        if output is None:
            raise OptionError("standard input needs -o FILE (or -o - / -c for standard output)")
        return output if not many else output / "stdin.mcz"
    if output is None:
        return compressed_name(path)
    return output / compressed_name(path).name if many else output


def _one(path: Path, out: Path, codec: str, options: dict[str, Any], block: str | None, asf: Path | None,
         fmt_name: str | None, rng: tuple[str | None, float | None, float | None], unit: str | None, force: bool,
         say: Say, precision: ExtrasPrecision | None = None) -> dict[str, Any]:
    """Compress one input to ``out``; return the figures printed (and given with --json)."""
    from mocapz._memory import release_free_memory
    from mocapz.api import compress_checked, decompress
    from mocapz.codecs import get_codec
    from mocapz.io import load
    from mocapz.metrics.c3d_extras import describe, extras_errors
    from mocapz.metrics.figures import evaluate, exact_copy, size_figures

    name = STDIN_NAME if str(path) == "-" else str(path)
    if str(path) == "-" and rng == (None, None, None) and unit is None:
        from mocapz.cli.streaming import compress_bvh_stream, is_bvh_stream

        stdin = click.get_binary_stream("stdin")
        if is_bvh_stream(stdin, fmt_name):  # a capture written to a pipe: each block out as soon as it is full
            return compress_bvh_stream(stdin, out, codec, options, block, force, name, say)
    if str(path) == "-":
        data_in = click.get_binary_stream("stdin").read()
        ext = f".{fmt_name.lower()}" if fmt_name else sniff(data_in)
        motion = load_bytes(data_in, ext)
        source_bytes: int | None = len(data_in)
    else:
        motion = load(path, asf) if asf else load(path)
        source_bytes = path.stat().st_size
    motion = with_unit(cut(motion, frame_slice(*rng, motion.frame_rate, motion.n_frames)), unit)
    info = get_codec(codec)
    if info.lossy and motion.kind in info.kinds and not any(options.get(n) is not None for n in TARGET_NAMES):
        say.info(f"{name}: no target given, the {codec} codec meets its default target: {DEFAULT_TARGET}")
    t0 = time.perf_counter()
    with say.progress(f"{name}: {codec}", total=motion.n_frames) as advance:
        advance.stage(f"encoding {motion.n_frames} frames")
        try:
            data = compress_checked(motion, info, options, block, advance, precision)
        except OptionError as exc:  # the options were checked: this one is about the file (exit code 1)
            raise MocapzError(exc.message, path=exc.path or name) from None
        except MocapzError as exc:
            raise exc.at(name) from None
        elapsed = time.perf_counter() - t0
        advance.stage("verifying every frame")
        release_free_memory()  # the encoder's freed arrays, not beside the decoder's (peak resident memory)
        decoded = decompress(data)
        rep = exact_copy(motion, decoded) or evaluate(motion, decoded)  # a lossless round trip: zero, no positions
        rest = extras_errors(motion, decoded)
    write_output(out, data, force)
    figs: dict[str, Any] = size_figures(motion, len(data), source_bytes)
    figs.update(input=name, output=str(out), codec=codec, frames=motion.n_frames,
                encode_ms_per_frame=1000 * elapsed / max(motion.n_frames, 1),
                distortion_pct=rep.distortion_pct, max_err=rep.max_err, max_err_cm=rep.max_err_cm, arms=rep.arms,
                arms_cm=rep.arms_cm)
    extras = sum(len(v) for k, v in Container.from_bytes(data).sections.items() if k.startswith(EXTRAS_PREFIX))
    figs["c3d_extras_bytes"] = extras
    if rest is not None:
        figs["c3d_extras"] = rest
    held = f" ({extras} of them the rest of the C3D: {describe(rest)})" if extras and rest else ""
    cm = rep.unit_cm is not None
    err = (f"max error {fmt(rep.max_err_cm, ' cm')}, ARMS {fmt(rep.arms_cm, ' cm')}" if cm
           else f"max error {fmt(rep.max_err)}, ARMS {fmt(rep.arms)} (file units)")
    say.info(f"{name} -> {out}: {figs['compressed_bytes']} bytes{held}, ratio {fmt(figs['ratio'])} to float32, "
             f"{fmt(figs['ratio_file'])} to the file; verified: d {rep.distortion_pct:.4g} %, {err}; "
             f"{codec}, {elapsed:.2f} s")
    say.detail(f"  {motion.n_frames} frames at {motion.frame_rate:g} Hz, {figs['encode_ms_per_frame']:.3f} ms/frame")
    return figs
