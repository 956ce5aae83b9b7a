"""The block index of a ``.mcz`` file: a clip coded as independent blocks of frames (random access).

A blocked file (container format version 2) holds, beside the clip-wide sections (the ``c3d.*`` extras),
the section ``blk`` (the index) and every block's codec sections under the name ``"{block}:{name}"``
(``"0:data"``, ``"1:data"``, ...). Blocks have ``block_frames`` frames each, the last one also what is left
(so no block is shorter than ``block_frames``, unless the clip is): block ``i`` covers frames
``[i * block_frames, (i + 1) * block_frames)``, the last one up to the clip's end.

``blk`` = uvarint ``block_frames``, uvarint block count. The container's section table locates every
block's bytes, so a reader decodes only the blocks a frame range needs.

A block's section equal to the previous block's section of the same name (a codec's per-column codes, its
header) is written once: the later block holds an empty section ``"={name}"`` instead (:func:`thin`,
:func:`thicken`; a streamed file's blocks do the same). Finding it back is a look-up in the section table,
so a frame range still decodes only its own blocks.
"""

from __future__ import annotations

from dataclasses import dataclass

from mocapz.errors import FormatError
from mocapz.format.entropy import read_uvarint, write_uvarint

INDEX = "blk"
SEPARATOR = ":"
SAME = "="  # a block's empty section "=name" stands for the previous block's section "name"
SAME_FROM = 2  # payloads of at least this many bytes are written once when equal (the mark costs about one)
CONTINUES = "<"  # a block's empty section "<": it decodes from the last frame of the block before it (a stream's)


@dataclass(frozen=True)
class BlockIndex:
    """Where the blocks of a clip of ``frames`` frames are: ``block_frames`` frames each (the last one up to
    ``2 * block_frames - 1``)."""

    frames: int
    block_frames: int

    @property
    def count(self) -> int:
        return max(1, self.frames // self.block_frames) if self.frames else 0

    def bounds(self, i: int) -> tuple[int, int]:
        """Frames ``[start, stop)`` of block ``i``."""
        return i * self.block_frames, self.frames if i == self.count - 1 else (i + 1) * self.block_frames

    def block_of(self, frame: int) -> int:
        return min(frame // self.block_frames, self.count - 1)

    def covering(self, start: int, stop: int) -> range:
        """The blocks holding frames ``[start, stop)`` (``0 <= start < stop <= frames``)."""
        return range(self.block_of(start), self.block_of(stop - 1) + 1)


def block_name(i: int, name: str) -> str:
    return f"{i}{SEPARATOR}{name}"


def pack(index: BlockIndex, blocks: list[dict[str, bytes]]) -> dict[str, bytes]:
    """The index section and every block's sections, renamed ``"{block}:{name}"``, in block order."""
    if len(blocks) != index.count:
        raise ValueError(f"{len(blocks)} blocks for an index of {index.count}")
    out = {INDEX: write_uvarint(index.block_frames) + write_uvarint(index.count)}
    previous = None
    for i, sections in enumerate(blocks):
        for name, payload in thin(previous, sections).items():
            if SEPARATOR in name:
                raise ValueError(f"section name {name!r} holds {SEPARATOR!r}, which blocks reserve")
            out[block_name(i, name)] = payload
        previous = sections
    return out


def thin(previous: dict[str, bytes] | None, sections: dict[str, bytes]) -> dict[str, bytes]:
    """A block's sections as written after a block of sections ``previous`` (None: the first block): those
    equal to the previous block's of the same name become the empty mark ``"=name"``."""
    out = {}
    for name, payload in sections.items():
        if name.startswith(SAME) or (name == CONTINUES and payload):
            raise ValueError(f"section name {name!r}: blocks reserve it")
        same = previous is not None and len(payload) >= SAME_FROM and previous.get(name) == payload
        out[SAME + name if same else name] = b"" if same else payload
    return out


def thicken(previous: dict[str, bytes] | None, sections: dict[str, bytes]) -> dict[str, bytes]:
    """Inverse of :func:`thin`: a block's sections with every mark replaced by the previous block's section
    (``previous``: that block's sections, as returned by this function); FormatError if a mark names none."""
    out = {}
    for name, payload in sections.items():
        if not name.startswith(SAME):
            out[name] = payload
            continue
        real = name[len(SAME):]
        if payload or previous is None or real not in previous or real in sections:
            raise FormatError(None, f"corrupted block (section {name!r} repeats no section of the block before)")
        out[real] = previous[real]
    return out


def unpack(sections: dict[str, bytes], frames: int) -> tuple[BlockIndex, list[dict[str, bytes]], dict[str, bytes]]:
    """``(index, every block's sections, the clip-wide sections)`` of a blocked file of ``frames`` frames;
    FormatError if the index does not fit the clip or a section names a block that does not exist."""
    data = sections.get(INDEX)
    if data is None:
        raise FormatError(None, "corrupted .mcz file (blocked, but no block index)")
    block_frames, pos = read_uvarint(data, 0)
    count, pos = read_uvarint(data, pos)
    if block_frames < 1 or count != BlockIndex(frames, max(block_frames, 1)).count:
        raise FormatError(None, f"corrupted block index ({count} blocks of {block_frames} frames "
                                f"for a clip of {frames} frames)")
    index = BlockIndex(frames, block_frames)
    if pos != len(data):
        raise FormatError(None, "corrupted block index (length)")
    blocks: list[dict[str, bytes]] = [{} for _ in range(count)]
    shared: dict[str, bytes] = {}
    for key, payload in sections.items():
        if key == INDEX:
            continue
        head, sep, name = key.partition(SEPARATOR)
        if not sep:
            shared[key] = payload
            continue
        if not head.isdigit() or int(head) >= count or not name:
            raise FormatError(None, f"corrupted .mcz file (section {key!r} names no block of the index)")
        blocks[int(head)][name] = payload
    for i in range(count):
        blocks[i] = thicken(blocks[i - 1] if i else None, blocks[i])
    return index, blocks, shared
