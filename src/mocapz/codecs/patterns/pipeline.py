"""One node's coding pipeline, over one clip or many (library mode).

segmentation (Algorithm 1) -> normalisation to the reference frame count -> adaptive K-means ->
pattern database coding -> per clip: (pattern index, original frame count) per segment, entropy coded ->
reconstruction (de-normalisation + boundary smoothing), which the encoder needs for the closed loop
(children are coded relative to their parent's *decoded* reference member).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mocapz.codecs.patterns.kmeans import MAX, adaptive_kmeans
from mocapz.codecs.patterns.normalise import denormalise, normalise, normalise_mask
from mocapz.codecs.patterns.quantise import encode_patterns
from mocapz.codecs.patterns.segment import lengths_of, partition
from mocapz.codecs.patterns.segments import encode_segments
from mocapz.codecs.patterns.smooth import smooth_boundaries


@dataclass
class Settings:
    """Encoder parameters (lengths relative to the ADDH).

    Attributes:
        theta: Algorithm 1 key-frame threshold, fraction of the ADDH.
        ratio: Algorithm 1 ratio threshold.
        tol: clustering distortion threshold (RMS member error bound), fraction of the ADDH.
        k0: initial number of clusters.
        metric: ``"max"`` (eq. 2) or ``"ave"`` (eq. 1).
        bits: quantisation bits of the pattern deltas over one range for the whole body (the paper's 8
            bits, applied to 120 fps data, gives 0.1 mm steps far below the clustering error: 3 is the
            default and the rate control searches 2 to 10).
        root_step: quantisation step of the root trajectory, fraction of the ADDH (None: 0.004 for the
            root marker, whose noise the closed loop passes on to every node; 0.02 for a root joint).
        max_length: longest segment in frames (keeps the normalisation small where a node never moves or
            is never observed).
    """

    theta: float = 0.01
    ratio: float = 2.0
    tol: float = 0.04
    k0: int = 10
    metric: str = MAX
    bits: int = 3
    root_step: float | None = None
    max_length: int = 256
    seed: int = 0
    heading: bool = True
    smooth: float | None = None

    def sigma(self) -> float:
        """Smoothing (frames) of decoded patterns: on for coarse quantisation (3 bits or fewer)."""
        if self.smooth is not None:
            return self.smooth
        return 0.7 if self.bits <= 3 else 0.0
    extra: dict = field(default_factory=dict)


@dataclass
class NodeSeries:
    """One node of one clip: ``x`` ``(T, D)`` values to code (gaps filled), ``observed`` ``(T, members)``."""

    x: np.ndarray
    observed: np.ndarray


@dataclass
class NodeCoded:
    """A coded node: database bytes, decoded patterns ``(K, L, D)``, per-clip streams and reconstructions."""

    db: bytes
    patterns: np.ndarray
    streams: list[bytes]
    recon: list[np.ndarray]
    segments: int
    clusters: int
    usage: np.ndarray


def half_window(length: int) -> int:
    """Boundary smoothing half-width for reference length ``L`` (both sides derive it from ``L``)."""
    return max(1, length // 3)


def code_node(series: list[NodeSeries], member_of: np.ndarray, weights: np.ndarray, settings: Settings,
              addh: float, step: float, prior_usage: bool = False) -> NodeCoded:
    """Segment, normalise, cluster and code one node over one or more clips.

    Args:
        series: the node's data in each clip.
        member_of: ``(D,)`` member index of every value column.
        weights: ``(members,)`` member weights relative to the body's mean weight (Algorithm 1's ``W``;
            the clustering distance scales each member's error by the square root of its weight, so a
            heavier member must be reproduced more closely).
        settings: encoder parameters.
        addh: length scale of the thresholds, file units.
        step: quantisation step of the pattern values, file units.
        prior_usage: library mode: pattern usage counts are shared (the per-clip index coders start from
            them), so they are returned and must be stored with the database.
    """
    d = series[0].x.shape[1]
    m = int(member_of.max()) + 1 if d else 0
    w = np.asarray(weights, dtype=np.float64)
    scale = np.sqrt(w)[member_of] if d else np.zeros(0)
    seg_starts, seg_lengths = [], []
    for s in series:
        frames = s.x.reshape(s.x.shape[0], -1)
        starts = partition(_grouped(frames, member_of, m), s.observed, w, settings.theta, addh,
                           settings.ratio, settings.max_length)
        seg_starts.append(starts)
        seg_lengths.append(lengths_of(starts, s.x.shape[0]))
    all_lengths = np.concatenate(seg_lengths) if seg_lengths else np.zeros(0, dtype=np.int64)
    length = max(2, int(round(all_lengths.mean()))) if all_lengths.size else 2
    ys, os_ = [], []
    for s, st, ln in zip(series, seg_starts, seg_lengths, strict=True):
        obs_cols = s.observed[:, member_of]
        ys.append(normalise(s.x, st, ln, length, None if obs_cols.all() else obs_cols).reshape(len(st), -1))
        os_.append(normalise_mask(obs_cols, st, ln, length).reshape(len(st), -1))
    y = np.concatenate(ys) if ys else np.zeros((0, length * d))
    o = np.concatenate(os_) if os_ else np.zeros((0, length * d))
    col_scale = np.tile(scale, length)
    cl = adaptive_kmeans(y * col_scale, o, settings.tol * addh, settings.k0, settings.metric,
                         per_member=max(1, d // max(m, 1)), seed=settings.seed)
    k = len(cl.centers)
    order, labels = first_use_order(cl.labels, k)
    centers = (cl.centers[order] / np.where(col_scale > 0, col_scale, 1.0)).reshape(k, length, d)
    db, patterns = encode_patterns(centers, step, settings.sigma())
    usage = np.bincount(labels, minlength=k).astype(np.int64)
    streams, recon = [], []
    pos = 0
    for s, ln in zip(series, seg_lengths, strict=True):
        lab = labels[pos : pos + len(ln)]
        pos += len(ln)
        streams.append(encode_segments(lab, ln, k, usage if prior_usage else None))
        recon.append(reconstruct(patterns, lab, ln, None if s.observed.all() else s.observed))
    return NodeCoded(db, patterns, streams, recon, int(all_lengths.size), k, usage)


def first_use_order(labels: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Renumber clusters in order of first use: ``(old index of each new index, new labels)``."""
    _, first = np.unique(labels, return_index=True)
    order = labels[np.sort(first)]
    new = np.empty(k, dtype=np.int64)
    new[order] = np.arange(len(order))
    return order, new[labels]


def _grouped(frames: np.ndarray, member_of: np.ndarray, m: int) -> np.ndarray:
    """``(T, D)`` -> ``(T, m, c)`` when every member has ``c`` columns, else zero-padded to the widest."""
    t, d = frames.shape
    counts = np.bincount(member_of, minlength=m)
    c = int(counts.max()) if m else 0
    if d == m * c and np.array_equal(member_of, np.repeat(np.arange(m), c)):
        return frames.reshape(t, m, c)
    out = np.zeros((t, m, c))
    slot = np.zeros(d, dtype=np.int64)
    seen = np.zeros(m, dtype=np.int64)
    for col, mem in enumerate(member_of):
        slot[col] = seen[mem]
        seen[mem] += 1
    out[:, member_of, slot] = frames
    return out


def reconstruct(patterns: np.ndarray, labels: np.ndarray, lengths: np.ndarray,
                observed: np.ndarray | None = None) -> np.ndarray:
    """Decoded node values ``(T, D)``: de-normalised patterns with boundaries smoothed (not at gap edges
    when ``observed`` ``(T, members)`` is given)."""
    if len(lengths) == 0:
        return np.zeros((0, patterns.shape[2]))
    frames = denormalise(patterns, labels, lengths)
    return smooth_boundaries(frames, lengths, half_window(patterns.shape[1]), observed)
