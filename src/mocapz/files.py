"""Motions from whatever a user points at: a motion file, a ``.mcz`` (decoded), or bytes from a pipe.

This is the one place that knows both the readers (:mod:`mocapz.io`) and the container (:mod:`mocapz.api`):
the CLI, the viewer and the benchmark all open their inputs through :func:`open_motion`. It also holds the
naming conventions of the command line (``clip.bvh`` <-> ``clip.bvh.mcz``).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

from mocapz.errors import FormatError
from mocapz.io import MOTION_EXTENSIONS
from mocapz.io.common import read_bytes
from mocapz.model.motion import AnyMotion

COMPRESSED_SUFFIX = ".mcz"
LIBRARY_SUFFIX = ".mczdb"
#: the extension a decoded clip gets from the format its container records
SOURCE_EXTENSIONS = {"bvh": ".bvh", "asfamc": ".amc", "c3d": ".c3d", "trc": ".trc"}
STDIN_NAME = "<stdin>"


@dataclass
class Opened:
    """A motion and what is known of how it was stored.

    Attributes:
        motion: the motion (decoded, for a ``.mcz``).
        codec: the codec that wrote the ``.mcz``, or ``None`` for a motion file.
        compressed_bytes: the ``.mcz`` size, or ``None``.
    """

    motion: AnyMotion
    codec: str | None = None
    compressed_bytes: int | None = None


def open_motion(path: str | os.PathLike[str], asf: str | os.PathLike[str] | None = None) -> Opened:
    """A motion file, or a ``.mcz`` decoded (by extension, or by content for other names)."""
    from mocapz.api import decompress, read_container
    from mocapz.io import load

    p = Path(path)
    if p.suffix.lower() == COMPRESSED_SUFFIX or (p.suffix.lower() not in MOTION_EXTENSIONS and _is_mcz(p)):
        data = read_bytes(p)
        box, _ = read_container(data, p)
        return Opened(decompress(data, p), box.codec, len(data))
    motion = load(p, asf) if asf else load(p)
    return Opened(motion)


def _is_mcz(p: Path) -> bool:
    try:
        with p.open("rb") as f:
            return f.read(4) == b"MCZ\x1a"
    except OSError:
        return False


def sniff(data: bytes) -> str:
    """The format of motion bytes: ``".mcz"``, ``".bvh"``, ``".c3d"``, ``".trc"`` or ``".amc"``.

    Raises FormatError (naming standard input) when the content is none of them.
    """
    if data[:4] == b"MCZ\x1a":
        return COMPRESSED_SUFFIX
    if len(data) >= 512 and data[1:2] == b"\x50":  # C3D: header byte 2 is the 0x50 key
        return ".c3d"
    head = data[:4096].lstrip(b"\xef\xbb\xbf \t\r\n")
    if head[:9].upper() == b"HIERARCHY":
        return ".bvh"
    if head.startswith(b"PathFileType"):
        return ".trc"
    if head[:1] in (b":", b"#") and (b":FULLY-SPECIFIED" in head.upper() or b":DEGREES" in head.upper()):
        return ".amc"
    raise FormatError(STDIN_NAME, "cannot tell the format of the data (BVH, C3D, TRC or .mcz expected; "
                                  "say it with --format)")


def load_bytes(data: bytes, ext: str, name: str = STDIN_NAME) -> AnyMotion:
    """A motion from the bytes of a motion file in format ``ext`` (errors name ``name``)."""
    from mocapz.io import load

    if ext == ".amc":
        raise FormatError(name, "an AMC needs its ASF skeleton beside it: give the .amc file, not a pipe")
    with tempfile.TemporaryDirectory(prefix="mocapz-") as tmp:
        path = Path(tmp) / f"stdin{ext}"
        path.write_bytes(data)
        try:
            motion = load(path)
        except FormatError as exc:
            raise FormatError(name, exc.problem, exc.line) from None
    motion.metadata.pop("path", None)
    motion.name = "stdin"
    return motion


def compressed_name(path: Path) -> Path:
    """Where ``mocapz compress`` writes by default: ``clip.bvh`` -> ``clip.bvh.mcz`` (beside it)."""
    return path.with_name(path.name + COMPRESSED_SUFFIX)


def decompressed_name(path: Path, source_format: str) -> Path:
    """Where ``mocapz decompress`` writes by default: ``clip.bvh.mcz`` -> ``clip.bvh``; a name without the
    source's extension gets it (``clip.mcz`` -> ``clip.bvh`` for a clip read from a BVH)."""
    stem = path.name[: -len(COMPRESSED_SUFFIX)] if path.name.lower().endswith(COMPRESSED_SUFFIX) else path.name
    out = path.with_name(stem)
    if out.suffix.lower() in MOTION_EXTENSIONS:
        return out
    return path.with_name(stem + SOURCE_EXTENSIONS.get(source_format, ".bvh"))
