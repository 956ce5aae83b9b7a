"""Library mode of the pattern codec: many clips coded with pattern databases shared per body part.

This is the pattern paper's headline property: clips of the same kind (same marker set, or same skeleton
layout) form a *group* whose body parts share one pattern database each, so the more clips a library
holds, the more often their segments reuse existing patterns and the higher the ratio (paper Figs.
10-11). Each clip keeps its own small streams (root trajectory, gap mask, per body part the pattern index
and frame count of every segment), so one clip is decoded from its streams and its group's databases
without decoding any other clip.

A group's shared sections are ``h`` (hierarchy with names), ``d<k>`` (pattern database of node ``k``) and
``u<k>`` (its usage counts, prior of the clips' index coders); a clip's own sections are those of a
single-clip stream (``p``, ``r``, ``g``, ``c``, ``s<k>``). The library file that stores them is
:mod:`mocapz.format.library`; this module sees only sections and typed headers.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mocapz.codecs.patterns.bodies import code_clips
from mocapz.codecs.patterns.decode import decode_clip, members_of
from mocapz.codecs.patterns.encode import target_from
from mocapz.codecs.patterns.hierarchy import Hierarchy
from mocapz.codecs.patterns.options import settings_from
from mocapz.codecs.patterns.pipeline import Settings
from mocapz.codecs.patterns.prepare import Prepared, marker_addh, prepare
from mocapz.codecs.patterns.quantise import decode_patterns
from mocapz.codecs.patterns.rate import search
from mocapz.codecs.patterns.skeletal import skeleton_addh
from mocapz.codecs.target import ErrorMetric
from mocapz.errors import FormatError
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


#: ``(coded groups, settings) -> library bytes``: how the caller stores a coded library
Writer = Callable[[list[CodedGroup], Settings], bytes]
#: ``(library bytes, clip index) -> decoded clip``: how the caller reads one clip back
Reader = Callable[[bytes, int], AnyMotion]


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


def encode_library(motions: list[AnyMotion], options: dict[str, Any], write: Writer, read: Reader) -> bytes:
    """Code clips into a library with shared databases; with a target, search the settings.

    Args:
        motions: the clips (each with frames).
        options: checked pattern options (:mod:`.options`); a target (``max_arms`` / ``max_distortion``)
            must hold for every clip, each in its own length unit.
        write: stores coded groups as library bytes.
        read: decodes one clip from those bytes (the chosen setting is checked by really decoding).
    """
    for m in motions:
        if m.n_frames == 0:
            raise FormatError(m.metadata.get("path", m.name), "clip has no frames")
    settings = settings_from(options)
    groups = groups_of(motions, options)
    targets = [t for t in (target_from(m, options) for m in motions) if t is not None]

    def run(s: Settings) -> tuple[list[np.ndarray], bytes, int]:
        coded = code_groups(motions, groups, s)
        decoded: list[np.ndarray] = [np.zeros(0)] * len(motions)
        for cg in coded:
            for i, d in zip(cg.members, cg.decoded, strict=True):
                decoded[i] = d
        data = write(coded, s)
        return decoded, data, len(data)

    if not targets:  # a target is given for every clip or for none
        return run(settings)[1]
    fixed = {k for k in ("tolerance", "bits") if options.get(k) is not None}

    def check(data: bytes) -> float:
        return max(t.score(ErrorMetric(m).of_motion(read(data, i)))
                   for i, (t, m) in enumerate(zip(targets, motions, strict=True)))

    addh = float(np.mean([g.prep.addh for g in groups]))
    return search("library", motions, settings, targets, fixed, addh, run, check)


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
