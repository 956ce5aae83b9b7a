"""``mocapz compress-db INPUT... -o LIBRARY.mczdb``: many clips into one pattern library.

Registered in :mod:`mocapz.cli.main` with ``cli.add_command(compress_db)``. One clip is read back with
``mocapz decompress LIBRARY.mczdb --clip NAME -o OUT`` and the clips are listed by ``mocapz info``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import click

from mocapz.cli.codec_flags import CodecCommand, codec_flags, given
from mocapz.cli.common import Say
from mocapz.codecs import get_codec
from mocapz.errors import OptionError


def _weights(pairs: tuple[str, ...], weights_file: str | None) -> Any:
    """Combine ``--weight LABEL=VALUE`` (repeatable) and ``--weights FILE`` into one option value."""
    if pairs and weights_file:
        raise OptionError("give either --weight LABEL=VALUE or --weights FILE, not both")
    if pairs:
        table = {}
        for item in pairs:
            label, sep, value = item.partition("=")
            if not sep or not label.strip():
                raise OptionError(f"--weight: expected LABEL=VALUE, got {item!r}")
            table[label.strip()] = value.strip()
        return table
    return weights_file


class LibraryCommand(CodecCommand):
    """compress-db: its help lists the pattern codec's options (the only codec with a library mode)."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        ctx.meta["mocapz.codec"] = "patterns"
        return click.Command.parse_args(self, ctx, args)


@click.command(name="compress-db", cls=LibraryCommand)
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True, help="output LIBRARY.mczdb")
@click.option("-f", "--force", is_flag=True, help="overwrite an existing output")
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
@click.option("--weight", "weight_pairs", multiple=True, help="marker weight LABEL=VALUE (repeatable)")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=1, show_default=True,
              help="worker processes reading the clips")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="read the clips on a Dask cluster (tcp://host:8786, or 'local')")
@click.option("--codec", default="patterns", show_default=True, help="the codec (only patterns has a library mode)")
@codec_flags("patterns")
def compress_db(inputs: tuple[Path, ...], output: Path, force: bool, as_json: bool, weight_pairs: tuple[str, ...],
                jobs: int, scheduler: str | None, codec: str, **codec_options: Any) -> None:
    """Compress INPUT files (.bvh, .amc, .c3d, .trc) or folders of them into one .mczdb library with shared
    pattern databases. Clips are read in parallel (--jobs / --scheduler); the databases are built over all
    of them. A clip that cannot be read is reported and left out (exit code 1)."""
    import sys

    from mocapz.errors import MocapzError
    from mocapz.io.common import atomic_write
    from mocapz.libraries import compress_library
    from mocapz.parallel.discover import discover
    from mocapz.parallel.load import load_many

    if get_codec(codec).name != "patterns":
        raise OptionError(f"compress-db: the {codec} codec has no library mode (only patterns has)")
    if output.suffix.lower() != ".mczdb":
        raise OptionError(f"{output}: a library file must end in .mczdb")
    w = _weights(weight_pairs, codec_options.pop("weights", None))
    options = get_codec("patterns").validate({**given(codec_options), "weights": w})
    paths: list[Path] = []
    for p in inputs:
        paths += discover(p) if p.is_dir() else [p]
    if output.exists() and not force:
        raise MocapzError(f"{output}: output exists (use -f to overwrite)")
    motions, failed = [], 0
    say = Say(quiet=as_json)
    with say.progress(f"compress-db: reading {len(paths)} clips", total=len(paths)) as advance:
        for path, motion, reason in load_many(paths, jobs=jobs, scheduler=scheduler):
            advance(1)
            if motion is None:
                failed += 1
                click.echo(f"mocapz: error: {path}: {reason}", err=True)
            else:
                motions.append(motion)
    if not motions:
        raise MocapzError("no clip could be read")
    t0 = time.perf_counter()
    frames = sum(m.n_frames for m in motions)
    with say.progress(f"compress-db: {len(motions)} clips, {frames} frames: pattern databases and encoding"):
        data = compress_library(motions, **options)
    elapsed = time.perf_counter() - t0
    atomic_write(output, lambda tmp: tmp.write_bytes(data), force=force)
    raw = sum(m.raw_bytes for m in motions)
    info = {"output": str(output), "clips": [m.name for m in motions], "frames": sum(m.n_frames for m in motions),
            "raw_bytes": raw, "compressed_bytes": len(data), "ratio": raw / len(data),
            "encode_s": elapsed}
    if as_json:
        click.echo(json.dumps(info))
    else:
        click.echo(f"{len(motions)} clips -> {output}: {len(data)} bytes, ratio {raw / len(data):.4g}, "
                   f"{elapsed:.2f} s" + (f"; {failed} clip(s) failed" if failed else ""), err=True)
    if failed:
        sys.exit(1)
