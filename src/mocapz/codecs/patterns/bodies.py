"""What is coded for each kind of data, and the coding of a set of clips node by node.

Marker data (the paper's case): the root marker's absolute positions, then every node's markers relative
to the decoded reference marker of its parent node (closed loop: the encoder uses what the decoder will
have, so errors do not pile up down the hierarchy). Skeletal data: the root joint's channels, then each
body part's joints as local rotation vectors (:mod:`.skeletal`).

:func:`code_clips` runs the pipeline for one clip (``.mcz``) or many sharing databases (``.mczdb``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapz.codecs import budget
from mocapz.codecs.gaps import encode_mask, fill_positions
from mocapz.codecs.patterns.decode import params_bytes
from mocapz.codecs.patterns.heading import measure_yaw, rotate, up_axis
from mocapz.codecs.patterns.hierarchy import Hierarchy
from mocapz.codecs.patterns.pipeline import NodeCoded, NodeSeries, Settings, code_node
from mocapz.codecs.patterns.quantise import delta_step, encode_trajectory
from mocapz.codecs.patterns.skeletal import HEAD_TO_HEIGHT, SkeletalFeatures, varying_positions
from mocapz.model.motion import MarkerMotion, Motion

MEASURED = 1  # nodes coded before the others' bytes are estimated from the smallest of them (budget.spend). One:
# over the 40 shared files at the default target, max distortion 0.36 %, max ARMS 5 mm and max error 3 cm, the model
# won only where its own bytes were 27-40 % of the cap, and a first node was at most 3.5 times a later one's bytes;
# stopping after the first node instead of the second (06_13's losing model: 1.03 -> 0.74 s, profiled)

MARKER_ROOT_STEP = 0.004  # root quantisation steps, fractions of the ADDH (see Settings.root_step)
JOINT_ROOT_STEP = 0.02


@dataclass
class CodedClips:
    """Result of :func:`code_clips`.

    Attributes:
        dbs: per node (index >= 1) the pattern database bytes (shared by all clips).
        usage: per node the pattern usage counts (library mode index-coder prior).
        clip_sections: per clip its own sections (``root``, ``gaps``, ``s<k>`` segment streams...).
        decoded: per clip the reconstruction (marker positions with NaN gaps, or channels).
        segments, clusters: totals over nodes (paper Table I).
    """

    dbs: list[bytes]
    usage: list[np.ndarray]
    clip_sections: list[dict[str, bytes]]
    decoded: list[np.ndarray]
    segments: int
    clusters: int


def code_clips(motions: list[Motion] | list[MarkerMotion], hier: Hierarchy, settings: Settings,
               weights: np.ndarray, addh: float, shared_prior: bool = False) -> CodedClips:
    """Code clips that share a hierarchy. ``weights`` ``(members,)`` over markers / joints (default 1).

    Runs with one BLAS thread: the many small matrix products of the clustering are several times
    slower when BLAS spreads them over threads.
    """
    from threadpoolctl import threadpool_limits

    weights = np.asarray(weights, dtype=np.float64)
    weights = weights / max(float(weights.mean()), 1e-12) if weights.size else weights
    with threadpool_limits(limits=1):
        if isinstance(motions[0], MarkerMotion):
            return _code_markers(motions, hier, settings, weights, addh, shared_prior)
        return _code_skeletal(motions, hier, settings, weights, addh, shared_prior)


def _finish(nodes: list[NodeCoded | None], sections: list[dict[str, bytes]], decoded: list[np.ndarray]) -> CodedClips:
    dbs, usage = [b""], [np.zeros(0, dtype=np.int64)]
    for k, nc in enumerate(nodes[1:], start=1):
        assert nc is not None
        dbs.append(nc.db)
        usage.append(nc.usage)
        for c, sec in enumerate(sections):
            sec[f"s{k}"] = nc.streams[c]
    return CodedClips(dbs, usage, sections, decoded,
                      sum(nc.segments for nc in nodes[1:] if nc), sum(nc.clusters for nc in nodes[1:] if nc))


def _code_markers(motions: list[MarkerMotion], hier: Hierarchy, settings: Settings, weights: np.ndarray,
                  addh: float, shared_prior: bool) -> CodedClips:
    filled = [fill_positions(m.positions) for m in motions]
    observed = [~m.missing for m in motions]
    root = hier.nodes[0].reference
    sections: list[dict[str, bytes]] = []
    decoded = []
    step = (MARKER_ROOT_STEP if settings.root_step is None else settings.root_step) * addh
    up = up_axis(motions[0].positions)
    yaws = []
    radius = addh / HEAD_TO_HEIGHT / 2.0
    for f, ob in zip(filled, observed, strict=True):
        sec: dict[str, bytes] = {"p": params_bytes(settings.heading, up)}
        vals = f[:, root]
        if settings.heading:
            vals = np.concatenate([vals, measure_yaw(f, ob, root, up)[:, None]], axis=1)
        data, rec = encode_trajectory(vals, np.array([step] * 3 + [step / radius] * (vals.shape[1] - 3)))
        sec["r"] = data
        if not ob.all():
            sec["g"] = encode_mask(~ob)
        dec = np.zeros_like(f)
        dec[:, root] = rec[:, :3]
        yaws.append(rec[:, 3] if settings.heading else None)
        sections.append(sec)
        decoded.append(dec)
    deltas = []
    for f, ob in zip(filled, observed, strict=True):
        for node in hier.nodes[1:]:
            rel = f[:, node.members] - f[:, hier.nodes[node.parent].reference][:, None]
            d = np.diff(rel, axis=0)
            d[~(ob[1:, node.members] & ob[:-1, node.members])] = np.nan
            deltas.append(d.ravel())
    qstep = delta_step(np.concatenate(deltas), settings.bits)
    nodes: list[NodeCoded | None] = [None]
    for node in hier.nodes[1:]:
        ref = hier.nodes[node.parent].reference
        mem = node.members
        series = [NodeSeries(_local(f[:, mem] - d[:, ref][:, None], y, up, True).reshape(f.shape[0], -1), ob[:, mem])
                  for f, d, ob, y in zip(filled, decoded, observed, yaws, strict=True)]
        nc = code_node(series, np.repeat(np.arange(len(mem)), 3), weights[mem], settings, addh, qstep,
                       shared_prior)
        for d, r, y in zip(decoded, nc.recon, yaws, strict=True):
            d[:, mem] = _local(r.reshape(d.shape[0], len(mem), 3), y, up, False) + d[:, ref][:, None]
        nodes.append(nc)
        _spend(sections, nodes, len(hier.nodes))
    for d, ob in zip(decoded, observed, strict=True):
        d[~ob] = np.nan
    return _finish(nodes, sections, decoded)


def _spend(sections: list[dict[str, bytes]], nodes: list[NodeCoded | None], count: int) -> None:
    """:func:`~mocapz.codecs.budget.spend` after a node: the bytes written so far, and from the first node on the
    nodes left (of the hierarchy's ``count``, its root coded apart) each as large as the smallest coded (the
    hierarchy's nodes are limbs of like size: CMU's skeletons 5.7 to 6.6 kB a node on 06_13)."""
    coded = [budget.section_bytes([nc.db, *nc.streams]) for nc in nodes if nc]
    least = min(coded) if len(coded) >= MEASURED else 0
    budget.spend(_written(sections, nodes), count - len(nodes), least)


def _written(sections: list[dict[str, bytes]], nodes: list[NodeCoded | None]) -> list[bytes]:
    """The sections' payloads coded so far: the clips' own and every coded node's database and streams."""
    return [v for sec in sections for v in sec.values()] + [p for nc in nodes if nc for p in (nc.db, *nc.streams)]


def _local(v: np.ndarray, yaw: np.ndarray | None, up: int, inverse: bool) -> np.ndarray:
    return v if yaw is None else rotate(v, yaw, up, inverse)


def _code_skeletal(motions: list[Motion], hier: Hierarchy, settings: Settings, weights: np.ndarray,
                   addh: float, shared_prior: bool) -> CodedClips:
    sections: list[dict[str, bytes]] = []
    root_step = JOINT_ROOT_STEP if settings.root_step is None else settings.root_step
    varying = varying_positions(motions[0].skeleton, [m.channels for m in motions])
    feats = [SkeletalFeatures(m.skeleton, addh, varying) for m in motions]
    decoded = []
    for m, sf in zip(motions, feats, strict=True):
        sec = {"p": params_bytes(False, 0),
               "r": encode_trajectory(*sf.root_values(m.channels, root_step * addh))[0]}
        const = sf.constant_columns(m.channels)
        if const:
            sec["c"] = const
        rec = sf.decode_root(sec["r"], m.n_frames)
        out = sf.apply_constants(np.zeros_like(m.channels), const)
        out[:, sf.root_columns] = rec
        sections.append(sec)
        decoded.append(out)
    values = [[sf.node_features(m.channels, node.members) for m, sf in zip(motions, feats, strict=True)]
              for node in hier.nodes[1:]]
    qstep = delta_step(np.concatenate([np.diff(x, axis=0).ravel() for per in values for x, _ in per]), settings.bits)
    nodes: list[NodeCoded | None] = [None]
    for node, per in zip(hier.nodes[1:], values, strict=True):
        member_of = per[0][1]
        series = [NodeSeries(x, np.ones((x.shape[0], len(node.members)), dtype=bool)) for x, _ in per]
        nc = code_node(series, member_of, weights[node.members], settings, addh, qstep, shared_prior)
        for out, sf, r in zip(decoded, feats, nc.recon, strict=True):
            sf.put_node(out, node.members, r)
        nodes.append(nc)
        _spend(sections, nodes, len(hier.nodes))
    return _finish(nodes, sections, decoded)
