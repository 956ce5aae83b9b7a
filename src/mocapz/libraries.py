"""The API of motion libraries (``.mczdb``): many clips, one codec, data shared between clips.

Clips with the same skeleton store it once; each codec's library mode (:mod:`mocapz.codecs.library`:
``pga`` shares one pose model per skeleton, ``patterns`` its body-part pattern databases, ``quant`` the
skeleton only) codes them in groups, and every clip meets its target as when compressed alone.

- :func:`compress_library` ``(motions, codec, **options) -> bytes``
- :func:`append_library` ``(data, motions, **options) -> bytes``: new clips added, the others' bytes kept
- :func:`read_clip` ``(data, name, frames=...) -> motion`` and :func:`extract_clip` ``(path, name, frames)``
  (reads only that clip's sections, its group's and its skeleton's from the file)
- :func:`list_clips`, :func:`describe_library`, :func:`verify_library` (a checksum per clip)

Options are checked here, once, against the codec's declarations. The file framing is
:mod:`mocapz.format.library`.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

from mocapz import blocking
from mocapz.codecs import get_codec
from mocapz.codecs.library import Done, LibraryMode, Work, quant_mode
from mocapz.errors import FormatError, MocapzError, OptionError
from mocapz.format.extras import attach, sections_of, split_sections
from mocapz.format.library import Library, clip_entry, read_library, read_members, unique_names
from mocapz.model.motion import AnyMotion

DEFAULT_CODEC = "patterns"
LIBRARY_CODECS = ("pga", "patterns", "quant")


def library_mode(codec: str) -> LibraryMode:
    """The library mode of a codec (OptionError for a codec without one)."""
    name = get_codec(codec).name
    if name == "quant":
        return quant_mode()
    if name == "pga":
        from mocapz.codecs.pga.library import MODE as PGA_MODE

        return PGA_MODE
    if name == "patterns":
        from mocapz.codecs.patterns.library import MODE as PATTERNS_MODE

        return PATTERNS_MODE
    raise OptionError(f"the {name} codec has no library mode (compress-db takes {', '.join(LIBRARY_CODECS)})")


def _checked(codec: str, motions: list[AnyMotion], options: dict[str, Any]) -> tuple[LibraryMode, dict[str, Any]]:
    mode = library_mode(codec)
    info = get_codec(mode.codec)
    checked = info.validate(options)
    for m in motions:
        if m.kind not in info.kinds:
            raise OptionError(f"{m.metadata.get('path', m.name)}: the {info.name} codec does not take {m.kind} "
                              f"data (it takes {' and '.join(info.kinds)} data)")
    return mode, checked


def _group_by(mode: LibraryMode, motions: list[AnyMotion]) -> dict[tuple, list[int]]:
    members: dict[tuple, list[int]] = {}
    for i, m in enumerate(motions):
        members.setdefault(mode.group_key(m), []).append(i)
    return members


def compress_library(motions: list[AnyMotion], codec: str = DEFAULT_CODEC, progress: Done | None = None,
                     jobs: int = 1, scheduler: str | None = None, **options: Any) -> bytes:
    """Compress clips into the bytes of a ``.mczdb`` library.

    Args:
        motions: the clips (names made unique: ``walk``, ``walk_2``...).
        codec: ``pga``, ``patterns`` (the default) or ``quant``.
        progress: called with a clip's frames as each clip is coded (a progress display).
        jobs, scheduler: where the clips are coded (:class:`~mocapz.parallel.pool.Pool`: 1, this process;
            N worker processes; a Dask scheduler): every clip is coded on its own (a group's shared model or
            databases first, here), so the bytes are the same whatever they are.
        **options: that codec's options (``docs/options.md``); the targets (``max_error``,
            ``max_distortion``, ``max_arms``) hold for every clip, each in its own length unit.

    Raises:
        OptionError: no clips, a codec without a library mode, an unknown option or a bad value.
        TargetError: a target the codec cannot meet on a clip.
    """
    if not motions:
        raise OptionError("compress-db: no input clips")
    mode, checked = _checked(codec, motions, options)
    lib = Library(index={"codec": mode.codec, "codec_version": mode.version, "skeletons": [], "groups": [],
                         "clips": [], "settings": {}})
    with _work(progress, jobs, scheduler, len(motions)) as work:
        _add(lib, mode, checked, motions, unique_names(motions), {}, work)
    return lib.to_bytes()


@contextlib.contextmanager
def _work(progress: Done | None, jobs: int, scheduler: str | None, clips: int) -> Iterator[Work]:
    """How the clips are coded: in this process, or on a pool of ``jobs`` workers (or a Dask scheduler)."""
    if jobs == 1 and scheduler is None:
        yield Work() if progress is None else Work(done=progress)
        return
    from mocapz.parallel.pool import Pool

    with Pool(jobs, scheduler, max_items=clips, preload=["mocapz.libraries", "mocapz.codecs.correction.wrap"]) \
            as pool:
        def each(fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
            for outcome in pool.imap(fn, items, ordered=True):
                if outcome.error is not None:
                    raise outcome.error
                yield outcome.value

        yield Work(each) if progress is None else Work(each, progress)


def _add(lib: Library, mode: LibraryMode, options: dict[str, Any], motions: list[AnyMotion], names: list[str],
         into: dict[tuple, int], work: Work) -> None:
    """Code ``motions`` into ``lib``: clips whose group key is in ``into`` (key -> group) are coded against
    that group's stored shared sections, the others in new groups (the clips run by ``work``)."""
    clips: list[tuple[int, dict[str, bytes], int]] = []  # (motion index, own sections, group)
    for key, members in _group_by(mode, motions).items():
        group_motions = [motions[i] for i in members]
        if key in into and mode.encode_into is not None:
            g = into[key]
            own = mode.encode_into(lib.group_sections(g), group_motions, options, work)
        else:
            g = len(lib.index["groups"])
            shared, own, info = mode.encode_group(group_motions, options, work)
            lib.add_group(g, shared)
            lib.index["groups"].append({**info, "kind": group_motions[0].kind, "clips": 0})
        clips += [(i, o, g) for i, o in zip(members, own, strict=True)]
    for i, own, g in sorted(clips, key=lambda c: c[0]):  # clips in the order given
        j = len(lib.index["clips"])
        sk = lib.add_clip(j, motions[i], {**own, **sections_of(motions[i])})
        lib.index["clips"].append(clip_entry(motions[i], names[i], g, sk))
        lib.index["groups"][g]["clips"] += 1


def append_library(data: bytes, motions: list[AnyMotion], path: str | os.PathLike[str] | None = None,
                   progress: Done | None = None, jobs: int = 1, scheduler: str | None = None,
                   **options: Any) -> bytes:
    """The library ``data`` with ``motions`` added; every clip already in it keeps its bytes.

    New clips with a group's layout are coded against that group's shared sections (pga: its pose model)
    where the codec can; patterns' databases depend on all their clips, so new pattern clips form a new
    group. A skeleton already stored is not stored again. ``options`` are the codec's (the library's codec,
    read from ``data``); a version 1 library cannot take new clips (compress its sources again).
    ``progress``: called with a clip's frames as each new clip is coded; ``jobs``, ``scheduler``: where they
    are coded (as :func:`compress_library`).
    """
    if not motions:
        raise OptionError("compress-db --append: no input clips")
    lib = Library.from_bytes(data, path)
    if lib.version < 2:
        raise FormatError(path, "a version 1 library cannot take new clips: compress its sources again")
    mode, checked = _checked(str(lib.index.get("codec")), motions, options)
    _check_version(lib, mode, path)
    into: dict[tuple, int] = {}
    if mode.encode_into is not None:
        for j in range(len(lib.index["clips"])):  # the group of every layout already in the library
            header = lib.clip_header(j)
            into.setdefault(mode.group_key(header.motion(_empty_values(header))), lib.group_of(j))
    with _work(progress, jobs, scheduler, len(motions)) as work:
        _add(lib, mode, checked, motions, unique_names(motions, lib.clip_names()), into, work)
    return lib.to_bytes()


def _empty_values(header: Any) -> Any:
    import numpy as np

    return np.zeros((0, *header.value_shape[1:]))


def _check_version(lib: Library, mode: LibraryMode, path: Any) -> None:
    if lib.index.get("codec_version") != mode.version:
        raise FormatError(path, f"library written by codec {lib.index.get('codec')!r} version "
                                f"{lib.index.get('codec_version')} (this mocapz reads {mode.codec} version "
                                f"{mode.version})")


def _mode_of(lib: Library, path: Any) -> LibraryMode:
    codec = lib.index.get("codec")
    try:
        mode = library_mode(str(codec))
    except OptionError:
        raise FormatError(path, f"library written by unknown codec {codec!r}") from None
    _check_version(lib, mode, path)
    return mode


def decode_clip(lib: Library, clip: str, path: str | os.PathLike[str] | None = None,
                frames: slice | range | tuple[int, int] | None = None) -> AnyMotion:
    """Decode clip ``clip`` of a parsed library (its own sections, its group's and its skeleton only), or
    only ``frames`` of it."""
    mode = _mode_of(lib, path)
    j = lib.clip_number(clip, path)
    try:
        header = lib.clip_header(j)
        start, stop = blocking.frame_range(frames, header.frames)
        own, c3d = split_sections(lib.clip_sections(j))
        motion = attach(mode.decode(lib.group_sections(lib.group_of(j)), own, header), c3d)
    except FormatError as exc:
        raise FormatError(path, exc.problem) from None
    except (ValueError, IndexError, KeyError, TypeError) as exc:
        raise FormatError(path, f"corrupted library clip {clip!r} ({type(exc).__name__}: {exc})") from None
    return motion if (start, stop) == (0, header.frames) else motion.slice(start, stop)


def read_clip(data: bytes, clip: str, path: str | os.PathLike[str] | None = None,
              frames: slice | range | tuple[int, int] | None = None) -> AnyMotion:
    """Decode one clip of library bytes (or only ``frames`` of it: a slice of the clip's frames)."""
    return decode_clip(Library.from_bytes(data, path), clip, path, frames)


def extract_clip(path: str | os.PathLike[str], clip: str,
                 frames: slice | range | tuple[int, int] | None = None) -> AnyMotion:
    """Decode one clip of a library file, reading only its own, its group's and its skeleton's sections
    (each checked against its checksum), not the other clips'."""
    return decode_clip(read_members(path, [clip]), clip, path, frames)


def list_clips(data: bytes, path: str | os.PathLike[str] | None = None) -> list[dict[str, Any]]:
    """Per clip: name, frames, frame rate, kind, source format, raw bytes, group, skeleton and its bytes in
    the library (own sections only)."""
    lib = Library.from_bytes(data, path)
    keys = ("name", "frames", "frame_rate", "kind", "format", "raw_bytes", "group", "skeleton")
    return [{k: c.get(k) for k in keys} | {"bytes": lib.clip_bytes(j)} for j, c in enumerate(lib.index["clips"])]


def verify_library(data: bytes, path: str | os.PathLike[str] | None = None, decode: bool = False,
                   progress: Done | None = None) -> dict[str, Any]:
    """Check a library: the whole file's checksum and every clip's (its own, its group's and its skeleton's
    sections); with ``decode``, every intact clip is decoded too. ``progress(frames)`` after each clip.

    Returns ``{"ok", "file_checksum", "clips": [{"name", "ok", "damaged", ...}]}``; a damaged index or
    framing raises FormatError (nothing can be told of the clips then).
    """
    import struct
    import zlib

    lib = Library.from_bytes(data, path, check=False)
    file_ok = len(data) >= 4 and zlib.crc32(data[:-4]) & 0xFFFFFFFF == struct.unpack("<I", data[-4:])[0]
    clips = []
    for j, name in enumerate(lib.clip_names()):
        bad = lib.damaged(j)
        entry: dict[str, Any] = {"name": name, "ok": not bad, "damaged": bad}
        if decode and not bad:
            try:
                decode_clip(lib, name, path)
            except MocapzError as exc:
                entry.update(ok=False, error=str(exc))
        clips.append(entry)
        if progress is not None:
            progress(lib.index["clips"][j]["frames"])
    return {"file": None if path is None else str(path), "format_version": lib.version, "file_checksum": file_ok,
            "per_clip_checksums": lib.version >= 2, "ok": file_ok and all(c["ok"] for c in clips), "clips": clips}


def describe_library(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Summary of a ``.mczdb`` file: its clips (names, frames, bytes), groups, skeletons and overall ratio."""
    p = Path(path)
    lib, data = read_library(p)
    _mode_of(lib, p)
    info = lib.summary(group_totals=("segments", "clusters") if lib.index.get("codec") == "patterns" else ())
    return {"file": str(p), "library_bytes": len(data), **info,
            "clip_bytes": [lib.clip_bytes(j) for j in range(len(lib.index["clips"]))],
            "ratio": info["raw_bytes"] / len(data) if data else None}
