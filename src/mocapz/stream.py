"""Compression of a live stream: frames in as they come, bytes out block by block, and back.

>>> enc = mocapz.StreamEncoder(template, codec="quant", max_error="1cm")   # template: the stream's layout
>>> out = enc.write(frames)          # (n, channels) or (n, markers, 3): bytes of the blocks now complete
>>> out += enc.close()               # the last block and the end record: a complete .mcz
>>> dec = mocapz.StreamDecoder()
>>> for motion in dec.feed(chunk): ...   # one motion per block, as soon as its bytes are in

A block is coded as soon as it is full (default 1 s of motion: the latency), as a clip of its own, as in a
file coded in blocks (:mod:`mocapz.blocking`), but continuing the block before it: the lossy codecs' correction
takes the decoded last frame of the block before as its first knot and predicts its first details across the edge
from the frames before that one (``c.head`` format 5; a skeleton block that the next one continues codes that last
frame tighter, :data:`~mocapz.codecs.correction.fit.HANDOVER_LEVELS`), so a block pays no
absolute values of its own; every ``key`` seconds (default 10) a block decodes on its own, where a reader of the
file can start (:func:`mocapz.blocking.iter_spans`). What a block's correction decides on the whole clip in a
file (foot contacts, body height) it decides on the last :data:`HISTORY_S` seconds (more than the contacts' floor
window, so a stream's contacts are the whole file's; of markers it holds the two lowest pairs, either of which the
whole file's lowest two may be), and the jitter allowance is spent block after block against the energy seen so
far (the accelerations across a block's first edge included), as the feet's speed is (a block on a model, which
starts afresh, counts the windows across its first edge); what the correction keeps from block to block (its
column layout, so the tolerance codes repeat and are written once) lives in ``cache["stream"]``. So memory stays
bounded whatever the stream's length.
The bytes (:mod:`mocapz.format.stream`) are a ``.mcz`` that :func:`mocapz.decompress` reads.
"""

from __future__ import annotations

import zlib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from mocapz import blocking
from mocapz.api import codec_of, decoder_errors
from mocapz.codecs import get_codec
from mocapz.codecs.correction.context import acceleration_energy
from mocapz.codecs.correction.fit import lifting_levels
from mocapz.codecs.target import ErrorMetric
from mocapz.errors import FormatError, OptionError
from mocapz.format import stream as framing
from mocapz.format.blocks import CONTINUES, thin
from mocapz.format.layout import decode_header, encode_layout
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, BlockOf, MarkerMotion, Motion

HISTORY_S = 10.0  # seconds of past frames a block's decisions look at
#: a stream's ``effort`` where none is given: its 1-s blocks are coded whole at each of the correction's lifting
#: depths (a file's default, fast, codes one; on the shared files' first 1,200 frames its quant streams were 5.8 %
#: larger, test_mocapbank.bvh's 36 %: which depth codes a second of motion smallest varies block to block)
STREAM_EFFORT = "medium"


def default_block(frame_rate: float) -> int:
    """About a second of frames, a whole number of the lossy codecs' knot spacings (:func:`.fit.lifting_levels`:
    a continued block's lifting then ends on a knot, with no padded frames flattening its last frames): 128
    frames at 120 fps, 64 at 60 fps, 32 at 30 fps."""
    span = 1 << lifting_levels(frame_rate)
    return max(1, round(frame_rate / span)) * span


class StreamEncoder:
    """Encode frames as they arrive.

    Args:
        template: a motion with the stream's layout (skeleton or marker labels, frame rate, units, decimals);
            its frames are not coded.
        codec: a registered codec name.
        block: block length (frames, ``"1s"``): the latency; default (None) about 1 s, a whole number of the
            correction's knot spacings (:func:`default_block`).
        key: how often a block decodes on its own, without the blocks before it (frames, ``"10s"``; 0: every
            block): a reader seeking into the file decodes from the last such block.
        **options: the codec's options (targets hold on every block, hence on the stream); ``effort`` is
            :data:`STREAM_EFFORT` unless given.
    """

    def __init__(self, template: AnyMotion, codec: str = "lossless", block: int | float | str | None = None,
                 key: int | float | str = "10s", **options: Any) -> None:
        self.info = get_codec(codec)
        if options.get("effort") is None and any(o.name == "effort" for o in self.info.options):
            options = {**options, "effort": STREAM_EFFORT}
        self.options = self.info.validate(options)
        if template.kind not in self.info.kinds:
            raise OptionError(f"the {self.info.name} codec does not take {template.kind} data")
        if "c3d" in template.metadata:
            raise OptionError("a stream carries marker positions only: compress a C3D file with its analogs and "
                              "parameters as a file (mocapz.compress)")
        self.template = template.slice(0, 0)
        self.block = default_block(template.frame_rate) if block is None \
            else blocking.block_frames(block, template.frame_rate, 1.0) or 1
        self.history = max(int(round(HISTORY_S * template.frame_rate)), 2)
        key_frames = blocking.block_frames(key, template.frame_rate, 0.0)
        self.key = max(1, round(key_frames / self.block))  # blocks from one that decodes alone to the next
        self.kept: dict[str, Any] = {}  # what the codec keeps from block to block (cache["stream"])
        self.before: np.ndarray | None = None  # the last frames as decoded (the next block continues from them)
        self.header: ClipHeader | None = None  # the decoder's header (the layout as written)
        self.blocks = 0
        self.pending: list[np.ndarray] = []
        self.past = template.values[:0]  # the last frames before the pending ones (context)
        empty = ErrorMetric(self.template)  # their positions (frames, points, 3) and present samples
        self.past_pos = empty.positions
        self.past_ok = np.ones(empty.positions.shape[:2], bool)
        self.frames = 0
        self.energy = 0.0  # the original's acceleration energy so far
        self.spent = 0.0  # acceleration energy the corrections added so far (less what they smoothed)
        self.skated: dict = {}  # the feet's added speed so far (:func:`mocapz.codecs.correction.feet.speed_sums`)
        self.edge: tuple | None = None  # the last frames as coded (:func:`mocapz.codecs.correction.context.tail`)
        self.crc = 0
        self.started = False
        self.closed = False
        self.last: dict[str, bytes] | None = None  # the previous block's sections (:func:`.blocks.thin`)
        self.names: list[str] | None = None  # the previous block's section names as written (a repeat record's)

    def write(self, frames: np.ndarray | AnyMotion) -> bytes:
        """Add frames ``(n, channels)`` (skeleton) or ``(n, markers, 3)`` (markers; NaN gaps) in file units;
        returns the bytes ready: the header on the first call, then every block completed."""
        if self.closed:
            raise OptionError("the stream is closed")
        values = frames.values if isinstance(frames, Motion | MarkerMotion) else np.asarray(frames, np.float64)
        if values.shape[1:] != self.template.values.shape[1:]:
            raise OptionError(f"frames of shape {values.shape[1:]} for a stream of {self.template.values.shape[1:]}")
        self.pending.append(np.array(values, dtype=np.float64))
        out = bytearray(self._start())
        have = sum(len(p) for p in self.pending)
        while have >= self.block:
            rows = np.concatenate(self.pending)
            out += self._encode(rows[:self.block], last=False)
            self.pending = [rows[self.block:]]
            have -= self.block
        return bytes(out)

    def close(self) -> bytes:
        """The last (shorter) block and the end record; the stream's bytes are then a complete ``.mcz``."""
        if self.closed:
            return b""
        out = bytearray(self._start())
        rows = np.concatenate(self.pending) if self.pending else self.template.values[:0]
        if len(rows):
            out += self._encode(rows, last=True)
        self.pending, self.closed = [], True
        end = framing.end_bytes(self.frames, {}, self.crc)
        return bytes(out + end)

    def _start(self) -> bytes:
        if self.started:
            return b""
        self.started = True
        layout = encode_layout(self.template)
        self.header = decode_header(layout)
        head = framing.header_bytes(self.info.name, self.info.version, layout)
        self.crc = zlib.crc32(head)
        return head

    def _encode(self, rows: np.ndarray, last: bool) -> bytes:
        past = self.past[-self.history:]
        field = "channels" if isinstance(self.template, Motion) else "positions"
        window = replace(self.template, **{field: np.concatenate([past, rows])})
        a, b = len(past), len(past) + len(rows)
        # positions of the new rows only (forward kinematics is per frame); the history's are kept
        metric = ErrorMetric(replace(self.template, **{field: rows}))
        valid = np.ones(metric.positions.shape[:2], bool) if metric.valid is None else metric.valid
        pos = np.concatenate([self.past_pos[-a:] if a else self.past_pos[:0], metric.positions])
        ok = np.concatenate([self.past_ok[-a:] if a else self.past_ok[:0], valid])
        lo = max(a - 2, 0)
        self.energy += float(acceleration_energy(pos[lo:b], ok[lo:b])[0].sum())
        # the clip so far, as the block's correction sees it: energy up to the block's end, the allowance spent
        cache = {"positions": (pos, ok), "energy": (self.energy, b), "jitter_spent": self.spent,
                 "skate_spent": self.skated, "stream": self.kept}
        if self.edge is not None:
            cache["edge"] = self.edge
        if self.blocks % self.key:
            cache["before"] = self.before
        else:
            cache["key"] = True  # a block that decodes alone: what the codec keeps from block to block starts anew
        if not last and (self.blocks + 1) % self.key:
            cache["followed"] = True  # the next block continues this one, from its last frames
        piece = window.slice(a, b)
        piece = replace(piece, metadata={**piece.metadata, "block_of": BlockOf(window, a, b, cache)})
        sections = self.info.encode(piece, **self.options)
        if cache.get("continued"):
            sections[CONTINUES] = b""
        # the block as the decoder will see it: its last frame is what the next block continues from (decoded only
        # where the next block may continue: not before a key block, nor for a codec that never continues)
        assert self.header is not None
        if cache.get("continuable") and (self.blocks + 1) % self.key:
            with decoder_errors(self.info.name, None):
                decoded = blocking.decode_block(self.info.decode, sections, self.header, len(rows), self.before)
            self.before = blocking.last_frames(decoded)
        else:
            self.before = None
        self.blocks += 1
        self.spent = float(cache.get("jitter_spent", self.spent))
        self.skated = cache.get("skate_spent", self.skated)
        self.edge = cache.get("edge", self.edge)
        self.past = np.concatenate([past, rows])[-self.history:]
        self.past_pos, self.past_ok = pos[-self.history:], ok[-self.history:]
        self.frames += len(rows)
        written = thin(self.last, sections)
        record = framing.block_bytes(len(rows), written, self.names)
        self.last, self.names = sections, framing.names_of(written)
        self.crc = zlib.crc32(record, self.crc)
        return record


class StreamDecoder:
    """Decode a stream as its bytes arrive: :meth:`feed` yields one motion per block completed."""

    def __init__(self, path: str | Path | None = None) -> None:
        self.reader = framing.StreamReader(keep=False)
        self.path = path
        self.header: ClipHeader | None = None
        self.info = None
        self.frames = 0
        self.before: np.ndarray | None = None  # the last frames decoded (a block may continue from them)

    def feed(self, data: bytes) -> list[AnyMotion]:
        """The motions of the blocks ``data`` completes (FormatError naming the stream if damaged)."""
        try:
            blocks = self.reader.feed(data)
        except FormatError as exc:
            raise FormatError(self.path, exc.problem) from None
        out = []
        for frames, sections in blocks:
            header = self._header()
            with decoder_errors(self.reader.stream.codec, self.path):  # type: ignore[union-attr]
                motion = blocking.decode_block(self.info.decode, sections, header, frames,  # type: ignore[union-attr]
                                               self.before)
            self.before = blocking.last_frames(motion)
            self.frames += frames
            out.append(motion)
        return out

    @property
    def complete(self) -> bool:
        """True once the end record is in (the stream checked whole)."""
        return self.reader.stream is not None and self.reader.stream.complete

    def _header(self) -> ClipHeader:
        if self.header is None:
            stream = self.reader.stream
            assert stream is not None
            self.info = codec_of(stream.codec, stream.codec_version, self.path)
            try:
                self.header = decode_header(stream.layout)
            except FormatError as exc:
                raise FormatError(self.path, exc.problem) from None
        return self.header
