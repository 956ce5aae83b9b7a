"""A ``.mcz`` file held open for random access: read and checked once, then any frame range decoded on demand.

>>> r = mocapz.open("walk.mcz")          # or the file's bytes
>>> len(r), r.frame_rate
(4906, 120.0)
>>> clip = r[2500:2520]                  # the values of those frames in a full decode

:func:`mocapz.decompress` with ``frames=`` reads the container, checks its CRC-32, parses its layout and splits
its blocks on every call; a :class:`Reader` does that once, so that a program taking many windows of one file (a
data loader sampling training windows, a player scrubbing a timeline) pays only for the frames it asks for.
:func:`mocapz.decompress` is itself a reader used once: both give the same motion to the bit.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from mocapz import blocking
from mocapz.codecs import CodecInfo, get_codec
from mocapz.errors import FormatError, OptionError
from mocapz.format import blocks
from mocapz.format.container import Container
from mocapz.format.extras import BLOCKS, attach, decode_extras, split_sections
from mocapz.format.layout import decode_header
from mocapz.format.stream import Stream, is_stream, read_stream
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, MarkerMotion


def read_container(data: bytes, path: str | Path | None = None) -> tuple[Container, ClipHeader]:
    """Parse container bytes and their layout header (errors name ``path``). A stream (format version 3)
    comes back as a container of its blocks' sections (``"{block}:{name}"``) and a header of all its frames."""
    if is_stream(data):
        stream, header = read_stream_header(data, path)
        sections = {f"{i}:{k}": v for i, b in enumerate(stream.blocks) for k, v in b.items()}
        return Container(stream.codec, stream.codec_version, stream.layout, {**sections, **stream.sections}), header
    box = Container.from_bytes(data, path)
    try:
        header = decode_header(box.layout)
    except FormatError as exc:
        raise FormatError(path, exc.problem) from None
    return box, header


def codec_of(name: str, version: int, path: str | Path | None) -> CodecInfo:
    """The registered codec a file names, at the version it was written with (FormatError otherwise)."""
    try:
        info = get_codec(name)
    except OptionError:
        raise FormatError(path, f"written by unknown codec {name!r}") from None
    check_codec_version(info, version, path)
    return info


def check_codec_version(info: CodecInfo, version: int, path: str | Path | None) -> None:
    if version != info.version:
        raise FormatError(path, f"codec {info.name!r} version {version} is not supported "
                                f"(this mocapz has version {info.version})")


@contextmanager
def decoder_errors(codec: str, path: str | Path | None) -> Iterator[None]:
    """A decoder's errors as one FormatError naming the file."""
    try:
        yield
    except FormatError as exc:
        raise FormatError(path, exc.problem) from None
    except (ValueError, IndexError, KeyError, TypeError, OverflowError) as exc:
        # the checksum held, so this is damaged content written with a valid CRC, or a decoder bug
        raise FormatError(path, f"the {codec} decoder failed ({type(exc).__name__}: {exc}): the file's "
                                f"content is damaged, or this is a mocapz bug (please report it)") from None


def with_extras(motion: AnyMotion, sections: dict[str, bytes], header: ClipHeader, start: int,
                stop: int, memo: dict[str, Any] | None = None) -> AnyMotion:
    """Frames ``[start, stop)`` of the clip with its C3D extras of those frames (only the blocks holding them
    decoded). ``memo``: a reader's, where extras coded in one block (decoded whole whatever the frames: their
    words are xz-packed whole) are kept once decoded, each range then a copy of its rows."""
    if not sections:
        return motion
    if not isinstance(motion, MarkerMotion):
        raise FormatError(None, "corrupted .mcz file (C3D sections in a skeletal clip)")
    whole = None
    if memo is not None and (start, stop) != (0, header.frames) and BLOCKS not in sections:
        whole = memo.get("c3d")
        if whole is None:
            whole = memo["c3d"] = decode_extras(sections, header.frames, len(header.labels))
    motion.metadata["c3d"] = whole.slice(start, stop) if whole is not None \
        else decode_extras(sections, header.frames, len(header.labels), start, stop)
    return motion


def read_stream_header(data: bytes, path: str | Path | None = None) -> tuple[Stream, ClipHeader]:
    """A complete stream and its layout header, with the frames of all its blocks (errors name ``path``)."""
    try:
        stream = read_stream(data)
        return stream, replace(decode_header(stream.layout), frames=stream.frames)
    except FormatError as exc:
        raise FormatError(path, exc.problem) from None


Frames = slice | range | tuple[int, int] | None


class Reader:
    """The frames of one ``.mcz`` file (a clip, a clip in blocks or a stream), decoded range by range.

    Args:
        data: the file's bytes.
        path: the file's name, for error messages.
        keep: keep what the windows of a clip in one block decode in common for the next reads (the correction's
            running values, chunk by chunk as reads reach them, and its zstd-packed streams unpacked; pga's
            trajectories and model: a few MB for a 5,000-frame clip, at most a few values per frame and column):
            a reader read many times; False for one read (:func:`mocapz.decompress`), which then decodes only
            what its frames need.

    Raises:
        FormatError: the bytes are not a valid ``.mcz`` (checked here, once: checksum, layout, blocks).
    """

    def __init__(self, data: bytes, path: str | PathLike[str] | None = None, keep: bool = True) -> None:
        self.path = None if path is None else str(path)
        self._parts: list[dict[str, bytes]] | None = None  # the blocks' sections (a clip in blocks, a stream)
        self._spans: list[tuple[int, int]] = []  # the blocks' frames [a, b)
        self._extras: dict[str, bytes] = {}
        self._empty_stream = False
        self._memo: dict[str, Any] | None = {} if keep else None  # what a clip's windows share (decode_window)
        if is_stream(data):
            stream, header = read_stream_header(data, self.path)
            self.info = codec_of(stream.codec, stream.codec_version, self.path)
            if stream.sections:
                raise FormatError(self.path, "corrupted streamed .mcz (unknown clip-wide sections "
                                             f"{sorted(stream.sections)})")
            self._parts, lengths = stream.blocks, stream.block_frames
            self._empty_stream = not stream.blocks
            self._sections: dict[str, bytes] = {}
        else:
            box, header = read_container(data, self.path)
            self.info = codec_of(box.codec, box.codec_version, self.path)
            self._sections, self._extras = split_sections(box.sections)
            lengths = []
            if box.blocked:
                with decoder_errors(box.codec, self.path):
                    index, self._parts, shared = blocks.unpack(self._sections, header.frames)
                    if shared:
                        raise FormatError(None, f"corrupted .mcz file (sections {sorted(shared)} outside its "
                                                "blocks)")
                lengths = [b - a for a, b in (index.bounds(i) for i in range(index.count))]
        self.header: ClipHeader = header
        ends = np.cumsum(lengths).tolist()
        self._spans = list(zip([0, *ends[:-1]], ends, strict=True)) if ends else []

    @property
    def codec(self) -> str:
        """The codec that wrote the file."""
        return self.info.name

    @property
    def n_frames(self) -> int:
        return self.header.frames

    @property
    def frame_rate(self) -> float:
        return float(self.header.frame_rate)

    def __len__(self) -> int:
        return self.header.frames

    def __getitem__(self, frames: slice) -> AnyMotion:
        if not isinstance(frames, slice):
            raise TypeError("a Reader is indexed by a slice of frames (reader[a:b])")
        return self.read(frames)

    def read(self, frames: Frames = None) -> AnyMotion:
        """The motion of ``frames`` (a slice, a range or ``(start, stop)``; default every frame): exactly those
        frames of a full decode, decoding only what they need (the blocks they lie in; in a lossy clip coded in
        one block, the parts of its streams they need)."""
        if self._empty_stream:
            return self.header.motion(np.zeros(self.header.value_shape))
        start, stop = blocking.frame_range(frames, self.header.frames)
        codec, path = self.info.name, self.path
        with decoder_errors(codec, path):
            if self._parts is not None:
                motion = blocking.decode_spans(self.info.decode, self._parts, self._spans, self.header, start, stop)
                return with_extras(motion, self._extras, self.header, start, stop, self._memo)
            if (start, stop) != (0, self.header.frames) and self.info.decode_window is not None:
                part = self.info.decode_window(self._sections, self.header, start, stop, memo=self._memo)
                if part is not None:  # only what the frames need was decoded
                    return with_extras(part, self._extras, self.header, start, stop, self._memo)
            motion = self.info.decode(self._sections, self.header)
            if (start, stop) == (0, self.header.frames):
                return attach(motion, self._extras)
            return with_extras(motion.slice(start, stop), self._extras, self.header, start, stop, self._memo)

    def iter_blocks(self, frames: Frames = None) -> Iterator[tuple[int, AnyMotion]]:
        """The frames of ``frames`` (default every frame) block by block, as each is decoded: ``(the number of
        frames selected in all, the next block's motion)``; a clip in one block comes in one piece. C3D extras are
        not attached (use :meth:`read`)."""
        start, stop = blocking.frame_range(frames, self.header.frames)
        if self._parts is None:
            yield stop - start, self.read(frames)
            return
        pieces = blocking.iter_spans(self.info.decode, self._parts, self._spans, self.header, start, stop)
        while True:
            with decoder_errors(self.info.name, self.path):
                piece = next(pieces, None)
            if piece is None:
                return
            yield stop - start, piece


def open(source: bytes | str | PathLike[str]) -> Reader:  # noqa: A001  (as gzip.open: the module's reader)
    """A :class:`Reader` of a ``.mcz`` file: its bytes, or its path (read whole, once)."""
    if isinstance(source, bytes | bytearray | memoryview):
        return Reader(bytes(source))
    path = Path(source)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FormatError(path, f"cannot read ({exc.strerror or exc})") from None
    return Reader(data, path)
