"""Library mode of the pattern codec: many clips coded with pattern databases shared per body part.

This is the pattern paper's headline property: clips of the same kind (same marker set, or same skeleton
layout) form a *group* whose body parts share one pattern database each, so the more clips a library
holds, the more often their segments reuse existing patterns and the higher the ratio (paper Figs.
10-11). Each clip keeps its own small streams (root trajectory, gap mask, per body part the pattern index
and frame count of every segment), so one clip is decoded from its streams and its group's databases
without decoding any other clip.

A group's shared sections are ``h`` (hierarchy with names), ``d<k>`` (pattern database of node ``k``) and
``u<k>`` (its usage counts, prior of the clips' index coders); a clip's own sections are those of a
single-clip stream (``p``, ``r``, ``g``, ``c``, ``s<k>``) plus the correction layer's ``c.*``
(:func:`encode_group`: every clip meets its target as when compressed alone). Libraries written before the
correction (format version 1) decode as they were. The databases depend on every clip of the group, so clips
appended later form a group of their own (:data:`MODE` has no ``encode_into``). The library file that stores
them is :mod:`mocapz.format.library`; this module sees only sections and typed headers.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from mocapz.codecs.correction.wrap import corrected, given_settings, native_targets
from mocapz.codecs.library import LibraryMode, Work
from mocapz.codecs.patterns import VERSION
from mocapz.codecs.patterns.bodies import code_clips
from mocapz.codecs.patterns.decode import decode_clip, members_of
from mocapz.codecs.patterns.encode import target_from
from mocapz.codecs.patterns.hierarchy import Hierarchy
from mocapz.codecs.patterns.options import OPTIONS, settings_from
from mocapz.codecs.patterns.pipeline import Settings
from mocapz.codecs.patterns.prepare import Prepared, marker_addh, prepare
from mocapz.codecs.patterns.quantise import decode_patterns
from mocapz.codecs.patterns.rate import search
from mocapz.codecs.patterns.skeletal import skeleton_addh
from mocapz.codecs.target import ErrorMetric, Target
from mocapz.errors import FormatError, TargetError
from mocapz.format.entropy import pack_uint64, unpack_uint64
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, MarkerMotion


@dataclass
class Group:
    """Clips sharing one hierarchy and its databases: their indices and the prepared hierarchy."""

    members: list[int]
    prep: Prepared


@dataclass
class CodedGroup:
    """One group coded with shared databases.

    Attributes:
        members: indices of the group's clips among all clips.
        shared: the group's shared sections (``h``, then ``d<k>``, ``u<k>`` per node).
        clips: per member its own sections.
        decoded: per member the encoder's reconstruction (identical to the decoder's).
        node_names: the hierarchy's node names.
        segments, clusters: totals over nodes (paper Table I).
    """

    members: list[int]
    shared: dict[str, bytes]
    clips: list[dict[str, bytes]]
    decoded: list[np.ndarray]
    node_names: list[str]
    segments: int
    clusters: int


def group_key(motion: AnyMotion) -> tuple:
    """Clips with equal keys (same marker labels, or same skeleton layout) share databases."""
    if isinstance(motion, MarkerMotion):
        return ("markers", tuple(motion.labels))
    sk = motion.skeleton
    return ("skeleton", tuple(sk.names), tuple(sk.channels), tuple(sk.rotation_order), tuple(sk.parents.tolist()))


def groups_of(motions: list[AnyMotion], options: dict[str, Any]) -> list[Group]:
    """Group the clips by layout and prepare each group's hierarchy (ADDH: the mean over its clips)."""
    members_of: dict[tuple, list[int]] = {}
    for i, m in enumerate(motions):
        members_of.setdefault(group_key(m), []).append(i)
    groups = []
    for members in members_of.values():
        prep = prepare(motions[members[0]], options.get("hierarchy"), options.get("weights"))
        prep.addh = float(np.mean([_addh(motions[i]) for i in members]))
        groups.append(Group(members, prep))
    return groups


def _addh(motion: AnyMotion) -> float:
    if isinstance(motion, MarkerMotion):
        return marker_addh(motion.labels, motion.positions)
    return skeleton_addh(motion.skeleton)


def code_groups(motions: list[AnyMotion], groups: list[Group], settings: Settings) -> list[CodedGroup]:
    """Code every group with databases shared by its clips."""
    out = []
    for group in groups:
        hier = group.prep.hier
        coded = code_clips([motions[i] for i in group.members], hier, settings, group.prep.weights,
                           group.prep.addh, shared_prior=True)
        shared = {"h": hier.to_bytes(with_names=True)}
        for k in range(1, len(hier.nodes)):
            shared[f"d{k}"] = coded.dbs[k]
            shared[f"u{k}"] = pack_uint64(coded.usage[k].astype(np.uint64))
        out.append(CodedGroup(group.members, shared, coded.clip_sections, coded.decoded, hier.names,
                              coded.segments, coded.clusters))
    return out


def encode_group(motions: list[AnyMotion], options: dict[str, Any], work: Work
                 ) -> tuple[dict[str, bytes], list[dict[str, bytes]], dict[str, Any]]:
    """Code one group of clips (same layout) with shared databases, then each clip's correction.

    As for a single clip (:mod:`mocapz.codecs.patterns`), the databases are coded with the settings as
    given (or the defaults) and the correction layer meets the targets; when the user fixed a setting and
    gives a distortion / ARMS target, the settings are searched first so that the databases alone meet it
    on every clip (each in its own length unit), checked by really decoding.

    Returns the group's shared sections, per clip its own sections, and the group's index entry.
    """
    for m in motions:
        if m.n_frames == 0:
            raise FormatError(m.metadata.get("path", m.name), "clip has no frames")
    settings = settings_from(options)
    groups = groups_of(motions, options)
    if len(groups) != 1:
        raise ValueError("encode_group takes clips of one layout")
    native = native_targets(motions[0], options, Target()) if given_settings(options, OPTIONS) else {}
    targets = [t for t in (target_from(m, native) for m in motions) if t is not None]
    if targets:
        headers = [ClipHeader.of(m) for m in motions]

        def run(s: Settings) -> tuple[list[np.ndarray], CodedGroup, int]:
            cg = code_groups(motions, groups, s)[0]
            return cg.decoded, cg, sum(len(v) for v in cg.shared.values()) + \
                sum(len(v) for own in cg.clips for v in own.values())

        def check(cg: CodedGroup) -> float:
            return max(t.score(ErrorMetric(m).of_motion(decode_member(h, cg.shared, own)))
                       for t, m, h, own in zip(targets, motions, headers, cg.clips, strict=True))

        fixed = {k for k in ("tolerance", "bits") if options.get(k) is not None}
        coded = search("library", motions, settings, targets, fixed, groups[0].prep.addh, run, check)
    else:
        coded = code_groups(motions, groups, settings)[0]
    coded.decoded.clear()  # every clip's reconstruction: not kept while the clips' corrections are coded (memory)
    own, alone = [], []
    # the correction alone: what the clip costs without databases (unless the user fixed the databases' settings)
    job = partial(_correct, coded.shared, options, not given_settings(options, OPTIONS))
    for m, (mine, without) in zip(motions, work.each(job, zip(motions, coded.clips, strict=True)), strict=True):
        own.append(mine)
        if without is not None:
            alone.append(without)
        work.done(m.n_frames)
    shared = coded.shared
    if alone and _size(alone) <= _size(own) + _size([shared]):
        # the databases cost more than they save (each clip decides for its own base, not for the databases):
        # every clip coded by its correction alone, no databases stored
        shared, own = {}, alone
    info = {"kind": motions[0].kind, "nodes": len(coded.node_names), "node_names": coded.node_names,
            "segments": coded.segments, "clusters": coded.clusters,
            "settings": {"theta": settings.theta, "ratio": settings.ratio, "tolerance": settings.tol,
                         "bits": settings.bits, "heading": settings.heading}}
    return shared, own, info


def _correct(shared: dict[str, bytes], options: dict[str, Any], without: bool,
             item: tuple[AnyMotion, dict[str, bytes]]) -> tuple[dict[str, bytes], dict[str, bytes] | None]:
    """A clip's own sections with the correction layer on its databases' coding, and (``without``) coded by the
    correction alone (a picklable job)."""
    m, clip = item

    def base(motion: AnyMotion, **o: Any) -> dict[str, bytes]:
        return dict(clip)

    mine = corrected(base, _decoder(shared), "patterns", OPTIONS)[0](m, **options)
    return mine, corrected(_no_base, _decoder({}), "patterns", OPTIONS)[0](m, **options) if without else None


def _no_base(motion: AnyMotion, **options: Any) -> dict[str, bytes]:
    raise TargetError("no base: the correction alone")


def _size(clips: list[dict[str, bytes]]) -> int:
    return sum(len(k) + 2 + len(v) for sections in clips for k, v in sections.items())


def _decoder(shared: Mapping[str, bytes]) -> Callable[[dict[str, bytes], ClipHeader], AnyMotion]:
    return lambda own, header: decode_member(header, shared, own)


def decode_corrected(shared: Mapping[str, bytes], own: dict[str, bytes], header: ClipHeader) -> AnyMotion:
    """One clip of a library from its group's databases and its own sections (correction applied)."""
    return corrected(lambda motion, **o: {}, _decoder(shared), "patterns", OPTIONS)[1](own, header)


def decode_member(header: ClipHeader, shared: Mapping[str, bytes], own: dict[str, bytes]) -> AnyMotion:
    """Decode one clip from its group's shared sections and its own sections.

    A missing shared section raises whatever ``shared[key]`` raises (the library reader names it).
    """
    hier = Hierarchy.from_bytes(shared["h"], members_of(header))
    dbs, priors = {}, {}
    for k in range(1, len(hier.nodes)):
        dbs[k] = decode_patterns(shared[f"d{k}"])[0]
        priors[k] = unpack_uint64(shared[f"u{k}"], len(dbs[k])).astype(np.int64)
    return decode_clip(header, hier, own, dbs, priors)


MODE = LibraryMode("patterns", VERSION, encode_group, None, decode_corrected, group_key)
