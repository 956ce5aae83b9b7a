"""The API of motion libraries (``.mczdb``): many clips coded with pattern databases shared per body part.

``compress_library(motions, **options) -> bytes``, ``read_clip(data, name) -> motion`` (one clip, decoded
from its own sections and its group's databases only) and ``describe_library(path)``. The pattern codec's
library mode is :mod:`mocapz.codecs.patterns.library`, the file framing :mod:`mocapz.format.library`; this
module joins them (options checked here, once, against the pattern codec's declarations).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from mocapz.codecs import get_codec
from mocapz.codecs.patterns import VERSION
from mocapz.codecs.patterns.library import CodedGroup, decode_member, encode_library
from mocapz.codecs.patterns.pipeline import Settings
from mocapz.errors import FormatError, OptionError
from mocapz.format.extras import attach, sections_of, split_sections
from mocapz.format.library import Library, clip_entry, read_library, unique_names
from mocapz.model.motion import AnyMotion

CODEC = "patterns"


def compress_library(motions: list[AnyMotion], **options: Any) -> bytes:
    """Compress clips into the bytes of a ``.mczdb`` library (pattern databases shared per body part).

    Options are those of the pattern codec (``docs/options.md``), checked like :func:`mocapz.compress`
    does. A target (``max_arms`` / ``max_distortion``) must hold for every clip.

    Raises:
        OptionError: no clips, or an unknown option or bad value.
        TargetError: a target the codec cannot meet on these clips.
    """
    if not motions:
        raise OptionError("compress-db: no input clips")
    checked = get_codec(CODEC).validate(options)
    names = unique_names(motions)

    extras = [sections_of(m) for m in motions]  # C3D extras: lossless, coded once

    def write(coded: list[CodedGroup], settings: Settings) -> bytes:
        return assemble(motions, names, coded, settings, extras).to_bytes()

    def read(data: bytes, clip: int) -> AnyMotion:
        return read_clip(data, names[clip])

    return encode_library(motions, checked, write, read)


def assemble(motions: list[AnyMotion], names: list[str], coded: list[CodedGroup], settings: Settings,
             extras: list[dict[str, bytes]] | None = None) -> Library:
    """The library of coded groups: each group's shared sections followed by its clips' (with their C3D
    extras' sections, :func:`mocapz.format.extras.sections_of`)."""
    lib = Library()
    clips: list[dict[str, Any]] = [{}] * len(motions)
    groups = []
    for g, cg in enumerate(coded):
        lib.add_group(g, cg.shared)
        for i, own in zip(cg.members, cg.clips, strict=True):
            lib.add_clip(i, motions[i], {**own, **(extras[i] if extras else {})})
            clips[i] = clip_entry(motions[i], names[i], g)
        groups.append({"kind": clips[cg.members[0]]["kind"], "clips": len(cg.members), "nodes": len(cg.node_names),
                       "node_names": cg.node_names, "segments": cg.segments, "clusters": cg.clusters})
    lib.index = {"codec": CODEC, "codec_version": VERSION, "groups": groups, "clips": clips,
                 "settings": {"theta": settings.theta, "ratio": settings.ratio, "tolerance": settings.tol,
                              "bits": settings.bits, "heading": settings.heading}}
    return lib


def _check_version(lib: Library, path: Any) -> None:
    if lib.index.get("codec") != CODEC or lib.index.get("codec_version") != VERSION:
        raise FormatError(path, f"library written by codec {lib.index.get('codec')!r} version "
                                f"{lib.index.get('codec_version')} (this mocapz reads patterns version {VERSION})")


def read_clip(data: bytes, clip: str, path: str | os.PathLike[str] | None = None) -> AnyMotion:
    """Decode one clip of a library, touching only its own streams and its group's databases."""
    lib = Library.from_bytes(data, path)
    _check_version(lib, path)
    j = lib.clip_number(clip, path)
    try:
        shared = lib.group_sections(lib.group_of(j))
        own, c3d = split_sections(lib.clip_sections(j))
        return attach(decode_member(lib.clip_header(j), shared, own), c3d)
    except FormatError as exc:
        raise FormatError(path, exc.problem) from None
    except (ValueError, IndexError, KeyError, TypeError) as exc:
        raise FormatError(path, f"corrupted library clip {clip!r} ({type(exc).__name__}: {exc})") from None


def describe_library(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Summary of a ``.mczdb`` file: its clips (names, frames), groups and overall ratio."""
    p = Path(path)
    lib, data = read_library(p)
    _check_version(lib, p)
    info = lib.summary(group_totals=("segments", "clusters"))
    return {"file": str(p), "library_bytes": len(data), **info,
            "ratio": info["raw_bytes"] / len(data) if data else None}
