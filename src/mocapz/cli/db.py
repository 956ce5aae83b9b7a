"""``mocapz compress-db INPUT... -o LIBRARY.mczdb [--codec pga|patterns|quant] [--append]``: many clips in one library.

Registered in :mod:`mocapz.cli.main` with ``cli.add_command(compress_db)`` (and ``verify``). One clip (or a
frame range of it) is read back with ``mocapz decompress LIBRARY.mczdb --clip NAME [--frames A:B] -o OUT``,
the clips are listed by ``mocapz info`` and checked by ``mocapz verify LIBRARY.mczdb``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import click

from mocapz.cli.codec_flags import CodecCommand, codec_flags, given
from mocapz.cli.common import Say, message_flags
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
    """compress-db: its help lists the options of the ``--codec`` given (patterns by default)."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        ctx.meta["mocapz.codec"] = "patterns"
        return super().parse_args(ctx, args)


@click.command(name="compress-db", cls=LibraryCommand)
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True, help="output LIBRARY.mczdb")
@click.option("-f", "--force", is_flag=True, help="overwrite an existing output")
@click.option("--append", is_flag=True, help="add the clips to the existing LIBRARY.mczdb (its clips keep their "
                                              "bytes; its codec is used)")
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
@click.option("--weight", "weight_pairs", multiple=True, help="marker weight LABEL=VALUE (repeatable; patterns)")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=1, show_default=True,
              help="worker processes reading and coding the clips (the same bytes whatever their number)")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="read and code the clips on a Dask cluster (tcp://host:8786, or 'local')")
@click.option("--codec", default=None, help="pga, patterns or quant  [default: patterns; with --append the "
                                            "library's]")
@message_flags
@codec_flags()
def compress_db(inputs: tuple[Path, ...], output: Path, force: bool, append: bool, as_json: bool,
                weight_pairs: tuple[str, ...], jobs: int, scheduler: str | None, codec: str | None, quiet: bool,
                verbose: bool, **codec_options: Any) -> None:
    """Compress INPUT files (.bvh, .amc, .c3d, .trc) or folders of them into one .mczdb library: clips with the
    same skeleton store it once, pga shares one pose model per skeleton, patterns its pattern databases; every
    clip meets the target as when compressed alone. With --append the clips are added to LIBRARY.mczdb (the
    clips in it keep their bytes). Clips are read and coded in parallel (--jobs / --scheduler). A clip that cannot be
    read, or whose data the codec does not take (markers for pga), is reported and left out (exit code 1)."""
    import sys

    from mocapz.errors import MocapzError
    from mocapz.format.library import read_library
    from mocapz.io.common import atomic_write
    from mocapz.libraries import append_library, compress_library, library_mode
    from mocapz.parallel.discover import discover
    from mocapz.parallel.load import load_many

    if output.suffix.lower() != ".mczdb":
        raise OptionError(f"{output}: a library file must end in .mczdb")
    old = b""
    if append:
        if force:
            raise OptionError("--append adds to the library: -f would overwrite it (give one of them)")
        lib, old = read_library(output)  # checked before any input is read
        have = str(lib.index.get("codec"))
        if codec is not None and get_codec(codec).name != have:
            raise OptionError(f"{output}: a {have} library (--append takes its codec; got --codec {codec})")
        codec = have
    codec = get_codec(codec or "patterns").name
    library_mode(codec)  # a codec without a library mode: exit code 2
    w = _weights(weight_pairs, codec_options.pop("weights", None))
    options = given(codec_options)
    if w is not None:
        options["weights"] = w
    options = get_codec(codec).validate(options)
    paths: list[Path] = []
    for p in inputs:
        paths += discover(p) if p.is_dir() else [p]
    if output.exists() and not force and not append:
        raise MocapzError(f"{output}: output exists (use -f to overwrite, or --append to add clips)")
    motions, failed = [], 0
    say = Say(quiet=as_json or quiet, verbose=verbose)
    kinds = get_codec(codec).kinds
    with say.progress(f"compress-db: reading {len(paths)} clips", total=len(paths)) as advance:
        for path, motion, reason in load_many(paths, jobs=jobs, scheduler=scheduler):
            advance(1)
            if motion is not None and motion.kind not in kinds:  # e.g. a marker file in a folder, for pga
                motion, reason = None, f"the {codec} codec does not take {motion.kind} data (it takes " \
                                       f"{' and '.join(kinds)} data)"
            if motion is None:
                failed += 1
                click.echo(f"mocapz: error: {path}: {reason}", err=True)
            else:
                motions.append(motion)
    if not motions:
        raise MocapzError("no clip could be read")
    t0 = time.perf_counter()
    frames = sum(m.n_frames for m in motions)
    say.detail(f"compress-db: {_clips(len(motions))}, {frames} frames, {codec} library mode")
    with say.progress(f"compress-db: coding {len(motions)} clips ({codec}), frames", total=frames) as advance:
        where = {"progress": advance, "jobs": jobs, "scheduler": scheduler}
        data = append_library(old, motions, output, **where, **options) if append \
            else compress_library(motions, codec, **where, **options)
    elapsed = time.perf_counter() - t0
    # written to a temporary file renamed into place: a failure leaves the old library as it was
    atomic_write(output, lambda tmp: tmp.write_bytes(data), force=force or append)
    raw = sum(m.raw_bytes for m in motions)
    info = {"output": str(output), "codec": codec, "clips": [m.name for m in motions], "frames": frames,
            "raw_bytes": raw, "compressed_bytes": len(data) - len(old), "library_bytes": len(data),
            "ratio": raw / max(len(data) - len(old), 1), "encode_s": elapsed}
    if as_json:
        click.echo(json.dumps(info))
    else:
        what = f"added to {output} ({len(data)} bytes)" if append else f"-> {output}: {len(data)} bytes"
        say.info(f"{_clips(len(motions))} {what}, ratio {info['ratio']:.4g}, "
                 f"{elapsed:.2f} s" + (f"; {failed} clip(s) failed" if failed else ""))
    if failed:
        sys.exit(1)


def _clips(n: int) -> str:
    return f"{n} clip" if n == 1 else f"{n} clips"


@click.command(name="verify")
@click.argument("library", type=click.Path(path_type=Path))
@click.option("--decode", is_flag=True, help="decode every clip too")
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
@message_flags
def verify(library: Path, decode: bool, as_json: bool, quiet: bool, verbose: bool) -> None:
    """Check a .mczdb library: the file's checksum and every clip's (exit code 1 if a clip is damaged). A
    damaged clip is one line on stderr, even with -q (every clip with -v); the last line says how the library is."""
    import sys

    from mocapz.errors import FormatError
    from mocapz.format.library import Library
    from mocapz.libraries import verify_library

    if not library.is_file():
        raise FormatError(library, "no such file")
    say = Say(quiet=as_json or quiet, verbose=verbose)
    data = library.read_bytes()
    total = sum(c["frames"] for c in Library.from_bytes(data, library, check=False).index["clips"])  # checked
    with say.progress(f"verify: {'decoding' if decode else 'checking'} {library.name}, frames",
                      total=total) as advance:
        report = verify_library(data, library, decode=decode, progress=advance)
    if as_json:
        click.echo(json.dumps(report))
    else:
        for c in report["clips"]:
            state = "ok" if c["ok"] else "DAMAGED (" + ", ".join(c["damaged"] or [c.get("error", "")]) + ")"
            if c["ok"]:
                say.detail(f"{c['name']}: {state}")
            else:  # an error: shown even with -q
                click.echo(f"{c['name']}: {state}", err=True)
        say.info(f"{library}: {'ok' if report['ok'] else 'damaged'} ({_clips(len(report['clips']))}, file "
                 f"checksum {'ok' if report['file_checksum'] else 'mismatch'})")
    if not report["ok"]:
        sys.exit(1)
