"""The small public API: ``compress(motion or path, codec, **options) -> bytes`` and
``decompress(bytes) -> motion``. Options are checked here, once, against the codec's declarations."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from os import PathLike
from pathlib import Path
from typing import Any

from mocapz import blocking
from mocapz.codecs import CodecInfo, get_codec
from mocapz.errors import FormatError, OptionError
from mocapz.format.container import Container
from mocapz.format.extras import PREFIX, sections_of
from mocapz.format.extras_precision import ExtrasPrecision
from mocapz.format.layout import encode_layout
from mocapz.model.motion import AnyMotion, MarkerMotion, Motion
from mocapz.reader import (  # noqa: F401  (re-exported: the readers' helpers)
    Reader,
    check_codec_version,
    codec_of,
    decoder_errors,
    read_container,
    read_stream_header,
    with_extras,
)


def compress(motion: AnyMotion | str | PathLike[str], codec: str = "lossless", *,
             block: int | float | str | None = None, analog_precision: Any = None, track_precision: Any = None,
             **options: Any) -> bytes:
    """Compress a motion into the bytes of a ``.mcz`` file.

    Args:
        motion: a :class:`~mocapz.Motion` or :class:`~mocapz.MarkerMotion`, or the path of a motion file.
        codec: a registered codec name, any case (``mocapz.codecs.codec_names()``).
        block: the clip is coded as independent blocks of this length, so that a frame range decodes only
            the blocks it needs (:func:`decompress` ``frames=``): frames (``240``), seconds (``"4s"``) or 0
            for one block; None: the codec's default (``CodecInfo.block_seconds``).
        analog_precision, track_precision: a C3D file's analog channels and model-output tracks come back
            bit for bit (None), or within this error in their own units: a number for all of them, or per
            name (``{"Fz1": 0.5}``, ``"angles=0.01,forces=0.1"``; :mod:`mocapz.format.extras_precision`).
        **options: that codec's options (``docs/options.md``; ``mocapz compress --codec NAME --help``).

    Raises:
        OptionError: an unknown codec or option, or a bad value (checked before anything is read).
        TargetError: a target the codec cannot meet on this clip.
    """
    info = get_codec(codec)
    checked = info.validate(options)
    precision = ExtrasPrecision.of(analog_precision, track_precision)
    blocking.block_frames(block, 1.0, 0.0)  # checked before anything is read or encoded
    if not isinstance(motion, Motion | MarkerMotion):
        from mocapz.io import load

        motion = load(Path(motion))
    return compress_checked(motion, info, checked, block, precision=precision)


def compress_checked(motion: AnyMotion, info: CodecInfo, checked: dict[str, Any],
                     block: int | float | str | None = None,
                     progress: Callable[[int], None] | None = None,
                     precision: ExtrasPrecision | None = None) -> bytes:
    """:func:`compress` with options already checked by ``info.validate`` and ``precision`` by
    :meth:`ExtrasPrecision.of` (the CLI and the batch workers check them once, before any input is read, and
    pass them on); ``progress(frames)`` after each block."""
    if motion.kind not in info.kinds:
        raise OptionError(f"the {info.name} codec does not take {motion.kind} data "
                          f"(it takes {' and '.join(info.kinds)} data)")
    per_block = blocking.block_frames(block, motion.frame_rate, info.block_seconds)
    sections = blocking.encode(info.encode, motion, checked, per_block, progress)
    if any(key.startswith(PREFIX) for key in sections):
        raise FormatError(None, f"the {info.name} codec wrote a section named {PREFIX}*, which is reserved")
    # the C3D extras, whatever the codec, in the codec's blocks
    sections = {**sections, **sections_of(motion, precision, per_block)}
    return Container(info.name, info.version, encode_layout(motion), sections).to_bytes()


def decompress(data: bytes, path: str | Path | None = None, *,
               frames: slice | range | tuple[int, int] | None = None) -> AnyMotion:
    """Decode the bytes of a ``.mcz`` file back into a motion, or only ``frames`` of it (a slice: the values of
    those frames in a full decode; a file coded in blocks decodes only the blocks they lie in): a
    :class:`~mocapz.reader.Reader` used once."""
    return Reader(data, path, keep=False).read(frames)


def iter_decompress(data: bytes, path: str | Path | None = None, *,
                    frames: slice | range | tuple[int, int] | None = None) -> Iterator[tuple[int, AnyMotion]]:
    """The frames of a ``.mcz`` (or ``frames`` of it) block by block, as each is decoded: ``(the number of frames
    selected in all, the next block's motion)``; a clip in one block comes in one piece. C3D extras are not
    attached (use :func:`decompress`)."""
    yield from Reader(data, path, keep=False).iter_blocks(frames)
