"""Which clips a folder holds, and where each one's ``.mcz`` goes.

:func:`discover` lists the motion files of a folder (``.bvh``, ``.amc``, ``.c3d``, ``.trc``; recursive;
sorted; hidden files skipped) and :func:`plan` maps each to a ``.mcz`` path in the output folder that
mirrors the input layout, as one :class:`~mocapz.parallel.clip.ClipJob` per clip.
"""

from __future__ import annotations

import os
from pathlib import Path

from mocapz.errors import FormatError, MocapzError
from mocapz.parallel.clip import ClipJob

BATCH_EXTENSIONS = (".bvh", ".amc", ".c3d", ".trc")
OUTPUT_SUFFIX = ".mcz"


def discover(input_dir: str | os.PathLike[str]) -> list[Path]:
    """Motion files under ``input_dir``, recursively, in a deterministic order.

    Files with a :data:`BATCH_EXTENSIONS` suffix (any case) are listed; names starting with ``.`` (hidden
    files and folders, temporary files) are skipped; symbolic links to folders are not followed. The order
    is that of the relative path components, so it does not depend on the file system.
    """
    root = Path(input_dir)
    if not root.exists():
        raise FormatError(root, "no such folder")
    if not root.is_dir():
        raise MocapzError(f"{root}: not a folder")
    errors: list[OSError] = []
    found: list[Path] = []
    for dirpath, dirnames, filenames in os.walk(root, onerror=errors.append):
        dirnames[:] = [d for d in dirnames if not d.startswith(".")]
        for name in filenames:
            if not name.startswith(".") and os.path.splitext(name)[1].lower() in BATCH_EXTENSIONS:
                found.append(Path(dirpath) / name)
    if errors:
        exc = errors[0]
        raise MocapzError(f"{exc.filename or root}: cannot list folder ({exc.strerror or exc})")
    return sorted(found, key=lambda p: p.relative_to(root).parts)


def plan(input_dir: str | os.PathLike[str], output_dir: str | os.PathLike[str]) -> list[ClipJob]:
    """The clips of ``input_dir`` (see :func:`discover`) and the ``.mcz`` file each is written to.

    ``a/b/walk.bvh`` goes to ``OUTDIR/a/b/walk.bvh.mcz``, as ``mocapz compress walk.bvh`` names it, so
    ``walk.bvh`` and ``walk.c3d`` never share an output and ``decompress`` restores the input names.
    """
    root = Path(input_dir).resolve()
    out_root = Path(output_dir).resolve()
    rels = [p.relative_to(root) for p in discover(root)]
    return [ClipJob(i, rel.as_posix(), str(root / rel), str(out_root / rel.parent / (rel.name + OUTPUT_SUFFIX)))
            for i, rel in enumerate(rels)]
