"""File formats: read any supported file into a Motion / MarkerMotion, write one back.

The format is chosen from the file extension; its module is imported on first use. Readers never know
codecs. One module per job:

* :mod:`~mocapz.io.bvh`: BVH files;
* :mod:`~mocapz.io.amc`: AMC motion files (with their skeleton), :mod:`~mocapz.io.asf` parses the ASF
  skeleton, :mod:`~mocapz.io.asf_write` produces the ASF written beside an AMC;
* :mod:`~mocapz.io.c3d`: C3D files through ezc3d, :mod:`~mocapz.io.c3d_checks` checks the raw file first,
  :mod:`~mocapz.io.c3d_pure` reads those ezc3d cannot read (SGI/MIPS storage, header errors) with the
  pure-Python ``c3d`` package, :mod:`~mocapz.io.c3d_raw` splits the file's words into marker positions
  and what else it holds, and puts them back together byte for byte;
* :mod:`~mocapz.io.trc`: TRC data rows, :mod:`~mocapz.io.trc_header` the TRC header lines;
* :mod:`~mocapz.io.common`: helpers every format shares (decimals, text, atomic output, units).
"""

from __future__ import annotations

import os
from pathlib import Path

from mocapz.errors import FormatError, MocapzError
from mocapz.model.motion import AnyMotion, MarkerMotion, Motion

SKELETAL_EXTENSIONS = (".bvh", ".amc")
MARKER_EXTENSIONS = (".c3d", ".trc")
MOTION_EXTENSIONS = SKELETAL_EXTENSIONS + MARKER_EXTENSIONS


def load(path: str | os.PathLike[str], asf: str | os.PathLike[str] | None = None) -> AnyMotion:
    """Read a motion file (``.bvh``, ``.amc`` with its ``.asf``, ``.c3d``, ``.trc``).

    For ``.amc`` the skeleton file is ``asf`` if given, else the ``.asf`` beside the AMC with the same
    stem, else the only ``.asf`` in that folder whose name starts the AMC's name (CMU ``01.asf`` for
    ``01_01.amc``).
    """
    p = Path(path)
    ext = p.suffix.lower()
    if not p.exists():
        raise FormatError(p, "no such file")
    if ext == ".bvh":
        from mocapz.io.bvh import read_bvh

        return read_bvh(p)
    if ext == ".amc":
        from mocapz.io.amc import read_asfamc

        return read_asfamc(p, asf)
    if ext == ".asf":
        raise FormatError(p, "an .asf holds only a skeleton; give the .amc motion file")
    if ext == ".c3d":
        from mocapz.io.c3d import read_c3d

        return read_c3d(p)
    if ext == ".trc":
        from mocapz.io.trc import read_trc

        return read_trc(p)
    raise FormatError(p, f"unknown motion file extension {ext!r} (expected one of {', '.join(MOTION_EXTENSIONS)})")


def save(motion: AnyMotion, path: str | os.PathLike[str], force: bool = False) -> list[Path]:
    """Write a motion to ``path`` in the format its extension names; return the files written.

    Skeletal motions go to ``.bvh`` / ``.amc`` (an ``.amc`` also writes its ``.asf`` beside it), marker
    motions to ``.c3d`` / ``.trc``. Existing files are kept unless ``force``; writes are atomic.
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in MOTION_EXTENSIONS:
        raise MocapzError(f"{p}: unknown output extension {ext!r} (expected one of {', '.join(MOTION_EXTENSIONS)})")
    if isinstance(motion, Motion):
        if ext == ".bvh":
            from mocapz.io.bvh import write_bvh

            write_bvh(motion, p, force=force)
            return [p]
        if ext == ".amc":
            from mocapz.io.amc import write_asfamc

            return write_asfamc(motion, p, force=force)
        raise MocapzError(f"{p}: skeletal motion can be written as .bvh or .amc, not {ext}")
    if isinstance(motion, MarkerMotion):
        if ext == ".c3d":
            from mocapz.io.c3d import write_c3d

            write_c3d(motion, p, force=force)
            return [p]
        if ext == ".trc":
            from mocapz.io.trc import write_trc

            write_trc(motion, p, force=force)
            return [p]
        raise MocapzError(f"{p}: marker data can be written as .c3d or .trc, not {ext}")
    raise TypeError(f"not a motion: {type(motion).__name__}")
