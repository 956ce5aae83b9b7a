"""``mocapz info FILE`` and ``mocapz eval ORIGINAL DECODED``: describe a file, measure a decoded result."""

from __future__ import annotations

from pathlib import Path

import click

from mocapz.cli.common import Say, cut, echo_json, fmt, frame_slice, message_flags, range_flags, unit_flag, with_unit
from mocapz.errors import MocapzError


@click.command()
@click.argument("file", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
def info(file: Path, as_json: bool) -> None:
    """Describe a motion file, a .mcz file or a .mczdb library."""
    from mocapz.cli.describe import describe

    d = describe(file)
    if as_json:
        echo_json(d)
        return
    for k, v in d.items():
        if isinstance(v, list) and len(v) > 12:
            v = ", ".join(map(str, v[:12])) + f", ... ({len(v)} in all)"
        elif isinstance(v, list):
            v = ", ".join(map(str, v))
        click.echo(f"{k:>20}: {fmt(v)}")


@click.command(name="eval")
@click.argument("original", type=click.Path(path_type=Path))
@click.argument("decoded", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
@click.option("--plot", type=click.Path(path_type=Path), default=None,
              help="also write per-point and over-time error plots (.png, .svg or .pdf; needs matplotlib)")
@click.option("-f", "--force", is_flag=True, help="overwrite an existing --plot file")
@range_flags
@unit_flag
@message_flags
def eval_cmd(original: Path, decoded: Path, as_json: bool, plot: Path | None, force: bool, frames: str | None,
             start: float | None, end: float | None, unit: str | None, quiet: bool, verbose: bool) -> None:
    """Error figures (METRICS.md) of DECODED (motion file or .mcz) against ORIGINAL.

    With a frame range, ORIGINAL is cut to it, and DECODED too unless it already has that many frames
    (a clip compressed from that range)."""
    from mocapz.files import open_motion
    from mocapz.io import load
    from mocapz.metrics.c3d_extras import describe, extras_errors
    from mocapz.metrics.figures import evaluate, size_figures

    with Say(quiet=quiet, verbose=verbose).progress("eval") as progress:  # stages on a terminal (stderr)
        progress.stage(f"reading {original.name}")
        orig = with_unit(load(original), unit)
        progress.stage(f"reading {decoded.name}")
        opened = open_motion(decoded)
        dec = opened.motion
        s = frame_slice(frames, start, end, orig.frame_rate, orig.n_frames)
        if s is not None:
            cut_orig = cut(orig, s)
            dec = dec if dec.n_frames == cut_orig.n_frames != orig.n_frames else cut(dec, s)
            orig = cut_orig
        progress.stage(f"error figures of {orig.n_frames} frames")
        try:
            rep = evaluate(orig, dec).as_dict()
        except MocapzError as exc:
            raise exc.at(decoded) from None
        if plot is not None:
            from mocapz.metrics.plots import plot_errors

            progress.stage(f"plotting {plot.name}")
            plot_errors(orig, dec, plot, force=force, compressed_bytes=opened.compressed_bytes)
            rep["plot"] = str(plot)
    if opened.compressed_bytes is not None:
        rep.update(size_figures(orig, opened.compressed_bytes))
    rest = extras_errors(orig, dec)
    if rest is not None:
        rep["c3d_extras"] = rest
    if as_json:
        echo_json(rep)
        return
    u = orig.unit_cm
    for k in ("distortion_pct", "arms", "max_err", "p99_err"):
        cm = rep.get(f"{k}_cm")
        extra = f"  ({cm:.4g} cm)" if cm is not None and u else ""
        click.echo(f"{k:>17}: {fmt(rep[k])}{'' if k == 'distortion_pct' else ' units'}{extra}")
    click.echo(f"{'bone_len_err':>17}: {fmt(rep['bone_len_err'])}")
    for k, what in (("foot_skate", "frame to frame"), ("foot_skate_window", "over 0.1 s windows")):
        fs = rep.get(f"{k}_cm_per_s")
        fs_cm = f"  ({fs:.4g} cm/s)" if fs is not None else ""
        click.echo(f"{k:>17}: {fmt(rep[k])} units/s{fs_cm}, {what}")
    click.echo(f"{'jitter_pct':>17}: {fmt(rep['jitter_pct'])} (added acceleration energy, %)")
    for k in ("raw_bytes", "compressed_bytes", "ratio", "ratio_file", "bytes_per_second", "plot"):
        if k in rep:
            click.echo(f"{k:>17}: {fmt(rep[k])}")
    if rest is not None:
        click.echo(f"{'rest of the C3D':>17}: {describe(rest)}")
