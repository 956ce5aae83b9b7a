"""Motion libraries (``.mczdb``): many clips coded with pattern databases shared per body part.

This is the pattern paper's headline property: clips of the same kind (same marker set, or same skeleton
layout) form a *group* whose body parts share one pattern database each, so the more clips a library
holds, the more often their segments reuse existing patterns and the higher the ratio (paper Figs.
10-11). Each clip keeps its own small streams (root trajectory, gap mask, per body part the pattern index
and frame count of every segment), so one clip is decoded from its streams and its group's databases
without decoding any other clip.

Byte layout::

    offset  size  field
    0       5     magic b"MCZL\\x1a"
    5       1     library format version (1)
    6       var   uvarint n, then n bytes: zstd-compressed JSON index (codec, groups, clips)
    ...     var   uvarint section count, then per section: 1 byte name length k, k bytes ASCII name,
                  uvarint length m, m bytes payload
    end-4   4     CRC-32 (zlib, little endian) of every byte before it

Sections: ``g<i>.h`` hierarchy of group ``i``; ``g<i>.d<k>`` pattern database of its node ``k``;
``g<i>.u<k>`` that database's usage counts (prior of the clips' index coders); ``c<j>.L`` layout header
of clip ``j`` (as in ``.mcz``); ``c<j>.<key>`` the clip's own pattern streams.
"""

from __future__ import annotations

import json
import os
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import zstandard

from mocapz.codecs.patterns import VERSION
from mocapz.codecs.patterns.bodies import code_clips
from mocapz.codecs.patterns.decode import decode_clip
from mocapz.codecs.patterns.encode import target_from
from mocapz.codecs.patterns.hierarchy import Hierarchy
from mocapz.codecs.patterns.options import settings_from
from mocapz.codecs.patterns.pipeline import Settings
from mocapz.codecs.patterns.prepare import Prepared, marker_addh, prepare
from mocapz.codecs.patterns.quantise import decode_patterns
from mocapz.codecs.patterns.rate import search
from mocapz.codecs.patterns.skeletal import skeleton_addh
from mocapz.codecs.target import ErrorMetric
from mocapz.errors import FormatError, MocapzError, OptionError
from mocapz.format.container import read_sections, seal, write_sections
from mocapz.format.entropy import pack_uint64, read_uvarint, safe_zstd_decompress, unpack_uint64, write_uvarint
from mocapz.format.layout import decode_header, encode_layout
from mocapz.model.motion import AnyMotion, MarkerMotion

MAGIC = b"MCZL\x1a"
FORMAT_VERSION = 1


# ------------------------------------------------------------------ container
@dataclass
class Library:
    """A parsed library: its JSON index and its raw (undecoded) sections."""

    index: dict[str, Any]
    sections: dict[str, bytes]

    def to_bytes(self) -> bytes:
        text = json.dumps(self.index, separators=(",", ":")).encode()
        head = zstandard.ZstdCompressor(level=19).compress(text)
        out = bytearray(MAGIC + bytes([FORMAT_VERSION]) + write_uvarint(len(head)) + head)
        out += write_sections(self.sections)
        return seal(out)

    @classmethod
    def from_bytes(cls, data: bytes, path: str | os.PathLike[str] | None = None) -> Library:
        try:
            return cls._parse(data)
        except FormatError as exc:
            raise FormatError(path, exc.problem) from None

    @classmethod
    def _parse(cls, data: bytes) -> Library:
        if len(data) < len(MAGIC) or data[: len(MAGIC)] != MAGIC:
            raise FormatError(None, "not a mocapz library (.mczdb): bad magic bytes")
        if len(data) < len(MAGIC) + 6:
            raise FormatError(None, "truncated library")
        (crc,) = struct.unpack("<I", data[-4:])
        if zlib.crc32(data[:-4]) & 0xFFFFFFFF != crc:
            raise FormatError(None, "corrupted or truncated library (checksum mismatch)")
        if data[len(MAGIC)] != FORMAT_VERSION:
            raise FormatError(None, f"unsupported library format version {data[len(MAGIC)]}")
        body = memoryview(data)[:-4]
        n, pos = read_uvarint(body, len(MAGIC) + 1)
        try:
            index = json.loads(safe_zstd_decompress(bytes(body[pos : pos + n]), 1 << 26, "library index"))
        except (ValueError, UnicodeDecodeError) as exc:
            raise FormatError(None, f"corrupted library index ({exc})") from None
        pos += n
        sections, pos = read_sections(body, pos, "library")
        if pos != len(body) or not isinstance(index, dict) or "clips" not in index:
            raise FormatError(None, "corrupted library (length mismatch or bad index)")
        return cls(index, sections)


# ------------------------------------------------------------------ writing
def _group_key(motion: AnyMotion) -> tuple:
    if isinstance(motion, MarkerMotion):
        return ("markers", tuple(motion.labels))
    sk = motion.skeleton
    return ("skeleton", tuple(sk.names), tuple(sk.channels), tuple(sk.rotation_order), tuple(sk.parents.tolist()))


def _unique_names(motions: list[AnyMotion]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for m in motions:
        base = m.name or "clip"
        seen[base] = seen.get(base, 0) + 1
        out.append(base if seen[base] == 1 else f"{base}_{seen[base]}")
    return out


def compress_library(motions: list[AnyMotion], **options: Any) -> bytes:
    """Compress clips into the bytes of a ``.mczdb`` library (pattern databases shared per body part).

    Options are those of the pattern codec (:mod:`mocapz.codecs.patterns.options`). A target
    (``max_arms`` / ``max_distortion``) must hold for every clip.
    """
    if not motions:
        raise OptionError("compress-db: no input clips")
    settings = settings_from(options)
    for m in motions:
        if m.n_frames == 0:
            raise FormatError(m.metadata.get("path", m.name), "clip has no frames")
    groups: dict[tuple, list[int]] = {}
    for i, m in enumerate(motions):
        groups.setdefault(_group_key(m), []).append(i)
    preps: list[tuple[list[int], Prepared]] = []
    for members in groups.values():
        first = motions[members[0]]
        prep = prepare(first, options.get("hierarchy"), options.get("weights"))
        prep.addh = float(np.mean([_addh(motions[i]) for i in members]))
        preps.append((members, prep))
    names = _unique_names(motions)
    targets = [target_from(m, options) for m in motions]

    def run(s: Settings) -> tuple[list[np.ndarray], Library, int]:
        lib, decoded = _build(motions, names, preps, s)
        return decoded, lib, len(lib.to_bytes())

    if targets[0] is None:
        return run(settings)[1].to_bytes()
    fixed = {k for k in ("tolerance", "bits") if options.get(k) is not None}

    def check(lib: Library) -> float:
        data = lib.to_bytes()
        return max(t.score(ErrorMetric(m).of_motion(read_clip(data, n)))
                   for t, m, n in zip(targets, motions, names, strict=True))

    addh = float(np.mean([p.addh for _, p in preps]))
    lib = search("library", motions, settings, targets[0], fixed, addh, run, check)
    return lib.to_bytes()


def _addh(motion: AnyMotion) -> float:
    if isinstance(motion, MarkerMotion):
        return marker_addh(motion.labels, motion.positions)
    return skeleton_addh(motion.skeleton)


def _build(motions: list[AnyMotion], names: list[str], preps: list[tuple[list[int], Prepared]],
           settings: Settings) -> tuple[Library, list[np.ndarray]]:
    sections: dict[str, bytes] = {}
    decoded: list[np.ndarray] = [np.zeros(0)] * len(motions)
    clips: list[dict[str, Any]] = [{}] * len(motions)
    group_info = []
    for g, (members, prep) in enumerate(preps):
        coded = code_clips([motions[i] for i in members], prep.hier, settings, prep.weights, prep.addh,
                           shared_prior=True)
        sections[f"g{g}.h"] = prep.hier.to_bytes(with_names=True)
        for k in range(1, len(prep.hier.nodes)):
            sections[f"g{g}.d{k}"] = coded.dbs[k]
            sections[f"g{g}.u{k}"] = pack_uint64(coded.usage[k].astype(np.uint64))
        for local, i in enumerate(members):
            m = motions[i]
            sections[f"c{i}.L"] = encode_layout(m)
            for key, payload in coded.clip_sections[local].items():
                sections[f"c{i}.{key}"] = payload
            decoded[i] = coded.decoded[local]
            clips[i] = {"name": names[i], "group": g, "frames": m.n_frames, "frame_rate": m.frame_rate,
                        "kind": "markers" if isinstance(m, MarkerMotion) else "skeleton",
                        "format": m.source_format, "raw_bytes": m.raw_bytes}
        group_info.append({"kind": clips[members[0]]["kind"], "clips": len(members), "nodes": len(prep.hier.nodes),
                           "node_names": prep.hier.names, "segments": coded.segments, "clusters": coded.clusters})
    index = {"codec": "patterns", "codec_version": VERSION, "groups": group_info, "clips": clips,
             "settings": {"theta": settings.theta, "ratio": settings.ratio, "tolerance": settings.tol,
                          "bits": settings.bits, "heading": settings.heading}}
    return Library(index, sections), decoded


# ------------------------------------------------------------------ reading
def _check_version(lib: Library, path: Any) -> None:
    if lib.index.get("codec") != "patterns" or lib.index.get("codec_version") != VERSION:
        raise FormatError(path, f"library written by codec {lib.index.get('codec')!r} version "
                                f"{lib.index.get('codec_version')} (this mocapz reads patterns version {VERSION})")


def clip_names(lib: Library) -> list[str]:
    return [c["name"] for c in lib.index["clips"]]


def read_clip(data: bytes, clip: str, path: str | os.PathLike[str] | None = None) -> AnyMotion:
    """Decode one clip of a library, touching only its own streams and its group's databases."""
    lib = Library.from_bytes(data, path)
    _check_version(lib, path)
    names = clip_names(lib)
    if clip not in names:
        shown = ", ".join(names[:20]) + (f", ... ({len(names)} in all)" if len(names) > 20 else "")
        raise MocapzError(f"{path or '<library>'}: no clip named {clip!r} (clips: {shown})")
    j = names.index(clip)
    g = int(lib.index["clips"][j]["group"])
    try:
        hier = Hierarchy.from_bytes(_get(lib, f"g{g}.h"))
        dbs, priors = {}, {}
        for k in range(1, len(hier.nodes)):
            dbs[k] = decode_patterns(_get(lib, f"g{g}.d{k}"))[0]
            priors[k] = unpack_uint64(_get(lib, f"g{g}.u{k}")).astype(np.int64)
        header = decode_header(_get(lib, f"c{j}.L"))
        prefix = f"c{j}."
        own = {key[len(prefix) :]: v for key, v in lib.sections.items() if key.startswith(prefix) and key != f"c{j}.L"}
        return decode_clip(header, hier, own, dbs, priors)
    except FormatError as exc:
        raise FormatError(path, exc.problem) from None
    except (ValueError, IndexError, KeyError, TypeError) as exc:
        raise FormatError(path, f"corrupted library clip {clip!r} ({type(exc).__name__}: {exc})") from None


def _get(lib: Library, key: str) -> bytes:
    if key not in lib.sections:
        raise FormatError(None, f"corrupted library (missing section {key!r})")
    return lib.sections[key]


def describe_library(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Summary of a ``.mczdb`` file: its clips (names, frames), groups and overall ratio."""
    p = Path(path)
    if not p.is_file():
        raise FormatError(p, "no such file")
    data = p.read_bytes()
    lib = Library.from_bytes(data, p)
    _check_version(lib, p)
    clips = lib.index["clips"]
    raw = sum(int(c["raw_bytes"]) for c in clips)
    shared = sum(len(v) for k, v in lib.sections.items() if k.startswith("g"))
    return {
        "file": str(p), "library_bytes": len(data), "codec": "patterns",
        "codec_version": lib.index["codec_version"], "clip_count": len(clips),
        "clips": [c["name"] for c in clips],
        "frames": [int(c["frames"]) for c in clips],
        "groups": len(lib.index["groups"]),
        "shared_database_bytes": shared,
        "segments": sum(int(g["segments"]) for g in lib.index["groups"]),
        "clusters": sum(int(g["clusters"]) for g in lib.index["groups"]),
        "raw_bytes": raw, "ratio": raw / len(data) if data else None,
    }
