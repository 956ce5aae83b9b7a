"""The ``mocapz`` command line: compress, decompress, info, eval.

Exit codes: 0 success, 1 error (one line on stderr), 2 usage error.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import click

from mocapz import __version__
from mocapz.errors import FormatError, MocapzError

# Codec options exposed on the command line: name -> (type, help). Each is passed to the codec only
# when given, so every codec validates its own options.
CODEC_OPTIONS: dict[str, tuple[Any, str]] = {
    "geodesics": (int, "PGA: number of principal geodesics k (default: chosen by the encoder)"),
    "variance": (float, "PGA: without --geodesics, keep the geodesics explaining this share (default 0.995)"),
    "lod_root": (int, "PGA: levels of detail dropped from the root trajectory"),
    "lod_effectors": (int, "PGA: levels of detail dropped from the end-effector trajectories"),
    "effectors": (str, "PGA: comma-separated end-effector joint names (default: the tree's extremities)"),
    "max_distortion": (float, "target: maximum distortion_pct (METRICS.md), searched by the encoder"),
    "max_error": (str, "target: maximum position error, file units or with a unit (1cm, 4mm)"),
    "max_arms": (str, "patterns: target ARMS, file units or with a unit (6.5mm)"),
    "theta": (float, "patterns: segmentation threshold, relative to the head-marker size (ADDH)"),
    "bits": (int, "quantisation bits"),
    "factor": (int, "subsample: keep every N-th frame"),
    "components": (int, "pca / segpca: number of principal components"),
    "paper": (bool, "PGA: decode from end effectors alone, as in the paper (no coded coordinates)"),
    "hierarchy": (str, "patterns: JSON file giving the body-part hierarchy"),
    "weights": (str, "patterns: per-marker weights: JSON file or LABEL=VALUE[,LABEL=VALUE]"),
    "tolerance": (float, "patterns: clustering threshold (MaxError bound), fraction of the ADDH"),
}


def _echo_json(obj: Any) -> None:
    click.echo(json.dumps(obj, indent=None, default=_json_default))


def _json_default(o: Any) -> Any:
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(type(o).__name__)


def _fmt(v: Any, unit: str = "") -> str:
    if v is None:
        return "n/a"
    if isinstance(v, float):
        return f"{v:.4g}{unit}"
    return f"{v}{unit}"


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="mocapz")
def cli() -> None:
    """Compress human motion-capture data (BVH, ASF/AMC, C3D, TRC)."""


def _codec_option_decorators(f: Any) -> Any:
    for name, (typ, help_text) in reversed(CODEC_OPTIONS.items()):
        flag = "--" + name.replace("_", "-")
        if typ is bool:
            f = click.option(flag, name, is_flag=True, default=None, help=help_text)(f)
        else:
            f = click.option(flag, name, type=typ, default=None, help=help_text)(f)
    return f


@cli.command()
@click.argument("input", type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True,
              help="output .mcz file (a folder when INPUT is a folder)")
@click.option("--codec", default="lossless", show_default=True, help="lossless, pga or patterns")
@click.option("--asf", type=click.Path(path_type=Path), default=None, help="skeleton for an .amc input")
@click.option("-f", "--force", is_flag=True, help="overwrite an existing output")
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=None,
              help="folder INPUT: worker processes (default: one per CPU; 1: serial)")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="folder INPUT: run on a Dask cluster (tcp://host:8786), or 'local' for a LocalCluster on "
                   "127.0.0.1 (needs pip install 'mocapz[dask]')")
@_codec_option_decorators
def compress(input: Path, output: Path, codec: str, asf: Path | None, force: bool, as_json: bool,
             jobs: int | None, scheduler: str | None, **codec_options: Any) -> None:
    """Compress INPUT (.bvh, .amc, .c3d, .trc) into OUTPUT.mcz, or every clip under folder INPUT into folder
    OUTPUT (one .mcz per clip, same layout; in parallel; exit code 1 if any clip failed)."""
    from mocapz.api import compress as do_compress
    from mocapz.io import load
    from mocapz.io.common import atomic_write
    from mocapz.metrics.figures import size_figures

    options = {k: v for k, v in codec_options.items() if v is not None}
    if input.is_dir():
        if asf is not None:
            raise MocapzError("--asf applies to one .amc file; in a folder each .amc uses the .asf beside it")
        from mocapz.cli.batch import run_batch_compress

        sys.exit(run_batch_compress(input, output, codec, options, jobs, scheduler, force, as_json))
    if jobs is not None or scheduler is not None:
        raise MocapzError("--jobs and --scheduler apply when INPUT is a folder")
    motion = load(input, asf) if asf else load(input)
    t0 = time.perf_counter()
    try:
        data = do_compress(motion, codec=codec, **options)
    except MocapzError as exc:
        if str(input) in str(exc):
            raise
        raise type(exc)(f"{input}: {exc}") if not isinstance(exc, FormatError) else exc from None
    elapsed = time.perf_counter() - t0
    atomic_write(output, lambda tmp: tmp.write_bytes(data), force=force)
    figs = size_figures(motion, len(data))
    figs.update(input=str(input), output=str(output), codec=codec, frames=motion.n_frames,
                encode_ms_per_frame=1000 * elapsed / max(motion.n_frames, 1))
    if as_json:
        _echo_json(figs)
    else:
        click.echo(f"{input} -> {output}: {figs['compressed_bytes']} bytes, ratio {_fmt(figs['ratio'])} "
                   f"(file ratio {_fmt(figs['ratio_file'])}), {codec}, {elapsed:.2f} s")


@cli.command()
@click.argument("input", type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True,
              help="output motion file: .bvh, .amc (+ .asf), .c3d or .trc")
@click.option("--clip", default=None, help="clip name inside a .mczdb library")
@click.option("-f", "--force", is_flag=True, help="overwrite existing outputs")
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
def decompress(input: Path, output: Path, clip: str | None, force: bool, as_json: bool) -> None:
    """Decode INPUT.mcz into a motion file (format from OUTPUT's extension)."""
    from mocapz.api import decompress as do_decompress
    from mocapz.io import MOTION_EXTENSIONS, save

    if output.suffix.lower() not in MOTION_EXTENSIONS:
        raise MocapzError(f"{output}: unknown output extension {output.suffix!r} "
                          f"(expected one of {', '.join(MOTION_EXTENSIONS)})")
    data = _read_bytes(input)
    t0 = time.perf_counter()
    if clip is None and input.suffix.lower() == ".mczdb":
        from mocapz.format.library import Library

        names = [c["name"] if isinstance(c, dict) else str(c) for c in Library.from_bytes(data, input).index["clips"]]
        raise MocapzError(f"{input}: a library holds several clips; choose one with --clip "
                          f"({', '.join(names[:10])}{', ...' if len(names) > 10 else ''})")
    if clip is not None:
        from mocapz.libraries import read_clip

        motion = read_clip(data, clip, input)
    else:
        motion = do_decompress(data, input)
    elapsed = time.perf_counter() - t0
    written = save(motion, output, force=force)
    info = {"input": str(input), "outputs": [str(p) for p in written], "frames": motion.n_frames,
            "decode_ms_per_frame": 1000 * elapsed / max(motion.n_frames, 1)}
    if as_json:
        _echo_json(info)
    else:
        click.echo(f"{input} -> {', '.join(info['outputs'])}: {motion.n_frames} frames, {elapsed:.3f} s")


def _read_bytes(path: Path) -> bytes:
    from mocapz.errors import FormatError

    if not path.exists():
        raise FormatError(path, "no such file")
    if path.is_dir():
        raise FormatError(path, "is a folder, not a file")
    return path.read_bytes()


def _load_any(path: Path) -> Any:
    """A motion from a motion file or a .mcz (decoded)."""
    from mocapz.io import load

    if path.suffix.lower() == ".mcz":
        from mocapz.api import decompress as do_decompress

        return do_decompress(_read_bytes(path), path)
    return load(path)


@cli.command()
@click.argument("file", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
def info(file: Path, as_json: bool) -> None:
    """Describe a motion file, a .mcz file or a .mczdb library."""
    from mocapz.cli.describe import describe

    d = describe(file)
    if as_json:
        _echo_json(d)
    else:
        for k, v in d.items():
            if isinstance(v, list) and len(v) > 12:
                v = ", ".join(map(str, v[:12])) + f", ... ({len(v)} in all)"
            elif isinstance(v, list):
                v = ", ".join(map(str, v))
            click.echo(f"{k:>20}: {_fmt(v)}")


@cli.command(name="eval")
@click.argument("original", type=click.Path(path_type=Path))
@click.argument("decoded", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
@click.option("--plot", type=click.Path(path_type=Path), default=None,
              help="also write per-point and over-time error plots (.png, .svg or .pdf; needs matplotlib)")
@click.option("-f", "--force", is_flag=True, help="overwrite an existing --plot file")
def eval_cmd(original: Path, decoded: Path, as_json: bool, plot: Path | None, force: bool) -> None:
    """Error figures (METRICS.md) of DECODED (motion file or .mcz) against ORIGINAL."""
    from mocapz.io import load
    from mocapz.metrics.figures import evaluate, size_figures

    orig = load(original)
    dec = _load_any(decoded)
    try:
        rep = evaluate(orig, dec).as_dict()
    except MocapzError as exc:
        raise MocapzError(f"{decoded}: {exc}") from None
    if plot is not None:
        from mocapz.metrics.plots import plot_errors

        plot_errors(orig, dec, plot, force=force,
                    compressed_bytes=decoded.stat().st_size if decoded.suffix.lower() == ".mcz" else None)
        rep["plot"] = str(plot)
    if decoded.suffix.lower() == ".mcz":
        rep.update(size_figures(orig, decoded.stat().st_size))
    if as_json:
        _echo_json(rep)
        return
    u = orig.skeleton.unit_cm if hasattr(orig, "skeleton") else orig.unit_cm
    for k in ("distortion_pct", "arms", "max_err", "p99_err"):
        cm = rep.get(f"{k}_cm")
        extra = f"  ({cm:.4g} cm)" if cm is not None and u else ""
        click.echo(f"{k:>16}: {_fmt(rep[k])}{'' if k == 'distortion_pct' else ' units'}{extra}")
    click.echo(f"{'bone_len_err':>16}: {_fmt(rep['bone_len_err'])}")
    fs = rep.get("foot_skate_cm_per_s")
    fs_cm = f"  ({fs:.4g} cm/s)" if fs is not None else ""
    click.echo(f"{'foot_skate':>16}: {_fmt(rep['foot_skate'])} units/s{fs_cm}")
    for k in ("raw_bytes", "compressed_bytes", "ratio", "ratio_file", "bytes_per_second", "plot"):
        if k in rep:
            click.echo(f"{k:>16}: {_fmt(rep[k])}")


def _register_commands() -> None:
    """Commands that live in their own modules."""
    from mocapz.cli.bench import bench
    from mocapz.cli.db import compress_db
    from mocapz.cli.view import view

    cli.add_command(view)
    cli.add_command(bench)
    cli.add_command(compress_db)


_register_commands()


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI, turning mocapz errors into one line on stderr and exit code 1."""
    try:
        cli.main(args=argv, prog_name="mocapz", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("mocapz: aborted", err=True)
        sys.exit(1)
    except click.UsageError as exc:
        exc.show()
        sys.exit(2)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except MocapzError as exc:
        click.echo(f"mocapz: error: {exc}", err=True)
        sys.exit(1)
    except KeyboardInterrupt:
        click.echo("mocapz: interrupted", err=True)
        sys.exit(130)
    except MemoryError:
        click.echo("mocapz: error: out of memory", err=True)
        sys.exit(1)
    except Exception as exc:  # noqa: BLE001 - last resort: one line, never a traceback
        click.echo(f"mocapz: internal error: {type(exc).__name__}: {exc} (please report)", err=True)
        sys.exit(1)
    sys.exit(0)


if __name__ == "__main__":  # pragma: no cover
    main()
