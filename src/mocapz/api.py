"""The small public API: ``compress(motion, **options) -> bytes`` and ``decompress(bytes) -> motion``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mocapz.codecs import get_codec
from mocapz.errors import FormatError, OptionError
from mocapz.format.container import Container
from mocapz.format.layout import decode_header, encode_layout
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, Motion


def compress(motion: AnyMotion, codec: str = "lossless", **options: Any) -> bytes:
    """Compress a motion into the bytes of a ``.mcz`` file.

    Args:
        motion: a :class:`~mocapz.Motion` or :class:`~mocapz.MarkerMotion`.
        codec: ``"lossless"``, ``"pga"`` (skeletal) or ``"patterns"``.
        **options: codec options (see ``mocapz compress --help``).
    """
    info = get_codec(codec)
    kind = "skeleton" if isinstance(motion, Motion) else "markers"
    if kind not in info.kinds:
        raise OptionError(f"codec {codec!r} does not handle {kind} data")
    sections = info.encode(motion, **options)
    return Container(info.name, info.version, encode_layout(motion), sections).to_bytes()


def read_container(data: bytes, path: str | Path | None = None) -> tuple[Container, ClipHeader]:
    """Parse container bytes and their layout header (errors name ``path``)."""
    box = Container.from_bytes(data, path)
    try:
        header = decode_header(box.layout)
    except FormatError as exc:
        raise FormatError(path, exc.problem) from None
    return box, header


def decompress(data: bytes, path: str | Path | None = None) -> AnyMotion:
    """Decode the bytes of a ``.mcz`` file back into a motion."""
    box, header = read_container(data, path)
    try:
        info = get_codec(box.codec)
    except OptionError:
        raise FormatError(path, f"written by unknown codec {box.codec!r}") from None
    if box.codec_version != info.version:
        raise FormatError(path, f"codec {box.codec!r} version {box.codec_version} is not supported "
                                f"(this mocapz has version {info.version})")
    try:
        return info.decode(box.sections, header)
    except FormatError as exc:
        raise FormatError(path, exc.problem) from None
    except (ValueError, IndexError, KeyError, TypeError) as exc:
        raise FormatError(path, f"corrupted {box.codec} payload ({type(exc).__name__}: {exc})") from None
