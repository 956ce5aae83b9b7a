"""Where the commands write: checked before any work, written atomically, ``-`` for standard output.

An existing output is refused (without ``-f``) before anything is read or computed; outputs are written to
a temporary file renamed into place (:func:`mocapz.io.common.atomic_write`), so a failure or Ctrl-C never
leaves a partial file, and nothing the user had is overwritten without ``-f``.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterable
from pathlib import Path

import click

from mocapz.errors import MocapzError
from mocapz.io.common import atomic_write


def is_stdout(path: Path | None) -> bool:
    return path is not None and str(path) == "-"


def check_outputs(paths: Iterable[Path], force: bool, folders_made: bool = False) -> None:
    """Refuse outputs that exist (without ``force``), that are folders, or whose folder is missing (unless
    the command makes it: ``folders_made``)."""
    seen: set[Path] = set()
    for p in paths:
        if is_stdout(p):
            continue
        if p in seen:
            raise MocapzError("two inputs would be written to the same output (use -o DIR)", path=p)
        seen.add(p)
        if p.is_dir():
            raise MocapzError("output is a folder", path=p)
        if p.exists() and not force:
            raise MocapzError("output exists (use -f to overwrite)", path=p)
        if not folders_made and not p.parent.exists():
            raise MocapzError(f"output folder {p.parent} does not exist", path=p)


def write_output(path: Path, data: bytes, force: bool) -> None:
    """``data`` to ``path`` atomically, or to standard output for ``-``."""
    if is_stdout(path):
        stream = click.get_binary_stream("stdout")
        stream.write(data)
        stream.flush()
        return
    atomic_write(path, lambda tmp: tmp.write_bytes(data), force=force)


def motion_to_stdout(motion: object, ext: str) -> None:
    """Write a motion in format ``ext`` to standard output (through a temporary file)."""
    from mocapz.io import save

    if ext == ".amc":
        raise MocapzError("an AMC comes with its ASF: write it to a file, not to standard output")
    with tempfile.TemporaryDirectory(prefix="mocapz-") as tmp:
        out = Path(tmp) / f"out{ext}"
        save(motion, out)  # type: ignore[arg-type]
        write_output(Path("-"), out.read_bytes(), force=True)
