"""Library modes of the lossy codecs: many clips coded with data shared per group (``compress-db``).

A codec's library mode (:class:`LibraryMode`) codes a *group* of clips (same skeleton, or same marker set):
the group's shared sections (a PGA pose model, pattern databases; none for quant) and, per clip, its own
sections, from which the clip is decoded with its group's shared sections alone. Every clip's own sections
carry the correction layer (:mod:`mocapz.codecs.correction`), so that its target holds exactly as when the
clip is compressed alone. Clips added later to a group (``--append``) are coded against its stored shared
sections (:attr:`LibraryMode.encode_into`) without touching the other clips, where the codec can.

The registry is :func:`mocapz.libraries.library_mode` (``pga``, ``patterns``, ``quant``); the file framing is
:mod:`mocapz.format.library`, which a codec never sees.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any

from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, MarkerMotion

Sections = dict[str, bytes]
#: called with a clip's frames as soon as that clip is coded (progress displays)
Done = Callable[[int], None]
#: ``each(fn, items)``: ``fn(item)`` for every item, in order (``fn`` and the items picklable: they may run on
#: a process pool); the first exception raised is raised
Each = Callable[[Callable[[Any], Any], Iterable[Any]], Iterator[Any]]


def serially(fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
    """:data:`Each` in this process."""
    for item in items:
        yield fn(item)


def _nothing(frames: int) -> None:
    pass


@dataclass(frozen=True)
class Work:
    """How a library mode runs its clips: ``each`` codes them (serially, or on the workers of
    ``compress-db --jobs``: every clip is coded on its own, so the bytes do not depend on where), ``done`` is
    told each clip's frames once it is coded."""

    each: Each = serially
    done: Done = _nothing


#: ``(clips, checked options, work) -> (the group's shared sections, per clip its own sections, what to record
#: of the group in the library's index)``
GroupEncoder = Callable[[list[AnyMotion], dict[str, Any], Work], tuple[Sections, list[Sections], dict[str, Any]]]
#: ``(the group's stored shared sections, new clips, checked options, work) -> per clip its own sections``
MemberEncoder = Callable[[Mapping[str, bytes], list[AnyMotion], dict[str, Any], Work], list[Sections]]
#: ``(the group's shared sections, the clip's own sections, its header) -> the clip``
MemberDecoder = Callable[[Mapping[str, bytes], Sections, ClipHeader], AnyMotion]


@dataclass(frozen=True)
class LibraryMode:
    """One codec's library mode.

    Attributes:
        codec: the codec's name (its options are the codec's, ``docs/options.md``).
        version: bumped whenever the bytes of its shared or own sections change.
        encode_group: codes a group of clips (targets met on every clip).
        encode_into: codes new clips against a group's stored shared sections; None when the codec cannot
            (its shared sections depend on every clip: new clips then form a group of their own).
        decode: decodes one clip.
        group_key: clips with equal keys may share a group.
    """

    codec: str
    version: int
    encode_group: GroupEncoder
    encode_into: MemberEncoder | None
    decode: MemberDecoder
    group_key: Callable[[AnyMotion], tuple]


def layout_key(motion: AnyMotion) -> tuple:
    """Same marker labels, or same skeleton hierarchy and channels (offsets may differ)."""
    if isinstance(motion, MarkerMotion):
        return ("markers", tuple(motion.labels))
    sk = motion.skeleton
    return ("skeleton", tuple(sk.names), tuple(sk.channels), tuple(sk.rotation_order), tuple(sk.parents.tolist()))


def _quant_alone(options: dict[str, Any], motion: AnyMotion) -> Sections:
    """A clip's sections as its single quant file's (a picklable job: the codec's encoder is a closure)."""
    from mocapz.codecs.baselines.quant import ENCODE

    return ENCODE(motion, **options)


def quant_mode() -> LibraryMode:
    """quant's library mode: the skeleton shared (by the library), each clip coded as alone."""
    from mocapz.codecs.baselines.quant import DECODE, VERSION

    def encode_into(shared: Mapping[str, bytes], motions: list[AnyMotion], options: dict[str, Any], work: Work
                    ) -> list[Sections]:
        out = []
        for m, own in zip(motions, work.each(partial(_quant_alone, options), motions), strict=True):
            out.append(own)
            work.done(m.n_frames)
        return out

    def encode_group(motions: list[AnyMotion], options: dict[str, Any], work: Work
                     ) -> tuple[Sections, list[Sections], dict[str, Any]]:
        return {}, encode_into({}, motions, options, work), {}

    return LibraryMode("quant", VERSION, encode_group, encode_into, lambda shared, own, header: DECODE(own, header),
                       layout_key)
