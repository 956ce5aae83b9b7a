"""``mocapz decompress INPUT... [-o OUTPUT]``: ``.mcz`` files (or folders of them) back to motion files.

``clip.bvh.mcz`` -> ``clip.bvh`` beside it (the format the container records when the name does not say
it); ``-o`` names the output (its extension picks the format) or, with several inputs or a folder, the
output folder; ``-o -`` / ``-c`` writes standard output (``--format`` says which format); ``-`` reads
standard input. ``LIBRARY.mczdb --clip NAME`` takes one clip out of a library.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import click

from mocapz.cli.common import Say, cut, each_input, finish, frame_slice, message_flags, range_flags
from mocapz.cli.outputs import check_outputs, is_stdout, motion_to_stdout
from mocapz.errors import FormatError, OptionError
from mocapz.files import COMPRESSED_SUFFIX, LIBRARY_SUFFIX, STDIN_NAME, decompressed_name
from mocapz.io import MOTION_EXTENSIONS
from mocapz.io.common import read_bytes

FORMATS = tuple(e.lstrip(".") for e in MOTION_EXTENSIONS)


@click.command()
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path, allow_dash=True))
@click.option("-o", "--output", type=click.Path(path_type=Path, allow_dash=True), default=None,
              help="output motion file (.bvh, .amc + .asf, .c3d, .trc; - for stdout), or a folder for several")
@click.option("-c", "--stdout", "to_stdout", is_flag=True, help="write the motion file to standard output")
@click.option("--format", "fmt_name", type=click.Choice(FORMATS, case_sensitive=False), default=None,
              help="output format (default: from -o's extension, else the source's)")
@click.option("--clip", default=None, help="clip name inside a .mczdb library")
@click.option("-f", "--force", is_flag=True, help="overwrite existing outputs")
@click.option("--json", "as_json", is_flag=True, help="print one JSON object on stdout")
@range_flags
@message_flags
def decompress(inputs: tuple[Path, ...], output: Path | None, to_stdout: bool, fmt_name: str | None,
               clip: str | None, force: bool, as_json: bool, frames: str | None, start: float | None,
               end: float | None, quiet: bool, verbose: bool) -> None:
    """Decode .mcz files (or folders of them, or a clip of a .mczdb library) into motion files."""
    say = Say(quiet, verbose)
    if to_stdout:
        if output is not None and not is_stdout(output):
            raise OptionError("give -c or -o, not both")
        output = Path("-")
    if is_stdout(output) and as_json:
        raise OptionError("--json prints on standard output: it cannot go with -o - / -c")
    files: list[tuple[Path, Path | None]] = []  # (input, its folder root when found in a folder)
    for p in inputs:
        if str(p) != "-" and p.is_dir():
            found = sorted(q for q in p.rglob(f"*{COMPRESSED_SUFFIX}") if not q.name.startswith("."))
            if not found:
                raise FormatError(p, f"no {COMPRESSED_SUFFIX} files in this folder")
            files += [(q, p) for q in found]
        else:
            files.append((p, None))
    many = len(files) > 1 or any(root is not None for _, root in files)
    if many and (is_stdout(output) or clip is not None):
        raise OptionError("standard output and --clip take one input")
    if output is not None and not many and not is_stdout(output) and output.suffix.lower() not in MOTION_EXTENSIONS:
        raise OptionError(f"{output}: unknown output extension {output.suffix!r} "
                          f"(expected one of {', '.join(MOTION_EXTENSIONS)})")
    results, failed = each_input(files, lambda item: _one(item[0], item[1], output, many, fmt_name, clip,
                                                          (frames, start, end), force, say), many)
    finish(results, many, as_json, failed)


def _one(path: Path, root: Path | None, output: Path | None, many: bool, fmt_name: str | None, clip: str | None,
         rng: tuple[str | None, float | None, float | None], force: bool, say: Say) -> dict[str, Any]:
    from mocapz.api import decompress as do_decompress
    from mocapz.api import read_container
    from mocapz.io import save

    name = STDIN_NAME if str(path) == "-" else str(path)
    library = path.suffix.lower() == LIBRARY_SUFFIX or clip is not None
    if str(path) == "-":
        data = click.get_binary_stream("stdin").read()
    else:  # a library file is not read whole: only the clip's sections are
        data = b"" if library and path.is_file() and clip is not None else read_bytes(path)
    t0 = time.perf_counter()
    if library:
        motion = _library_clip(data, path, clip)
    else:
        _, header = read_container(data, name)
        out = _output_for(path, root, output, many, fmt_name, header.source_format)
        if not is_stdout(out):
            check_outputs([out], force, folders_made=many)
        sel = frame_slice(*rng, header.frame_rate, header.frames)
        if is_stdout(out) and out_ext(fmt_name, header.source_format) == ".bvh" and header.kind == "skeleton":
            from mocapz.cli.streaming import decompress_bvh_to_stdout

            n = decompress_bvh_to_stdout(data, name, sel)  # block by block, as each is decoded
            say.info(f"{name} -> -: {n} frames, {time.perf_counter() - t0:.3f} s")
            return {"input": name, "outputs": ["-"], "frames": n}
        # a file coded in blocks decodes only the blocks the range needs
        with say.progress(f"{name}: decoding"):
            motion = do_decompress(data, name, frames=sel)
        rng = (None, None, None)
    motion = cut(motion, frame_slice(*rng, motion.frame_rate, motion.n_frames))
    elapsed = time.perf_counter() - t0
    if path.suffix.lower() == LIBRARY_SUFFIX or clip is not None:
        out = _output_for(path, root, output, many, fmt_name, motion.source_format)
    if is_stdout(out):
        motion_to_stdout(motion, out_ext(fmt_name, motion.source_format))
        written = ["-"]
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        with say.progress(f"{name}: writing {out.name} ({motion.n_frames} frames)"):
            written = [str(p) for p in save(motion, out, force=force)]
    say.info(f"{name} -> {', '.join(written)}: {motion.n_frames} frames, {elapsed:.3f} s")
    return {"input": name, "outputs": written, "frames": motion.n_frames,
            "decode_ms_per_frame": 1000 * elapsed / max(motion.n_frames, 1)}


def out_ext(fmt_name: str | None, source_format: str) -> str:
    """The extension of the format written: ``--format``, else the source's."""
    return f".{fmt_name.lower()}" if fmt_name else _source_ext(source_format)


def _source_ext(source_format: str) -> str:
    from mocapz.files import SOURCE_EXTENSIONS

    return SOURCE_EXTENSIONS.get(source_format, ".bvh")


def _output_for(path: Path, root: Path | None, output: Path | None, many: bool, fmt_name: str | None,
                source_format: str) -> Path:
    if is_stdout(output):
        return Path("-")
    if str(path) == "-":
        if output is None:
            raise OptionError("standard input needs -o FILE (or -o - / -c)")
        path = Path("stdin.mcz")
    default = decompressed_name(path, source_format)
    if fmt_name:
        default = default.with_suffix(f".{fmt_name.lower()}")
    if output is None:
        return default
    if not many:
        return output
    rel = default.relative_to(root) if root is not None else Path(default.name)
    return output / rel


def _library_clip(data: bytes, path: Path, clip: str | None) -> Any:
    from mocapz.format.library import Library
    from mocapz.libraries import extract_clip, read_clip

    if clip is None:
        names = Library.from_bytes(data, path).clip_names()
        raise OptionError(f"{path}: a library holds several clips; choose one with --clip "
                          f"({', '.join(names[:10])}{', ...' if len(names) > 10 else ''})")
    if not data and clip is not None:  # only the clip's sections are read (and checked)
        return extract_clip(path, clip)
    return read_clip(data, clip, path)
