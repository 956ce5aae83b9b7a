"""Pattern decoder: root trajectory, then every node from its pattern database and segment stream."""

from __future__ import annotations

from typing import Any

import numpy as np

from mocapz.codecs.gaps import decode_mask
from mocapz.codecs.patterns.heading import rotate
from mocapz.codecs.patterns.hierarchy import Hierarchy
from mocapz.codecs.patterns.pipeline import reconstruct
from mocapz.codecs.patterns.quantise import decode_patterns, decode_trajectory
from mocapz.codecs.patterns.segments import decode_segments
from mocapz.codecs.patterns.skeletal import SkeletalFeatures
from mocapz.errors import FormatError
from mocapz.model.header import ClipHeader

FLAG_HEADING = 1


def params_bytes(heading: bool, up: int) -> bytes:
    """The small ``p`` section: flags and the vertical axis."""
    return bytes([FLAG_HEADING if heading else 0, up])


def members_of(header: ClipHeader) -> int:
    """The number of markers or joints a clip's hierarchy divides."""
    return len(header.labels) if header.skeleton is None else header.skeleton.n_joints


def decode(sections: dict[str, bytes], header: ClipHeader) -> Any:
    """Decode a single-clip ``.mcz`` payload into a Motion / MarkerMotion."""
    hier = Hierarchy.from_bytes(_need(sections, "h"), members_of(header))
    if header.frames == 0:
        return decode_clip(header, hier, sections, {})
    dbs = {k: decode_patterns(_need(sections, f"d{k}"))[0] for k in range(1, len(hier.nodes))}
    return decode_clip(header, hier, sections, dbs)


def _need(sections: dict[str, bytes], key: str) -> bytes:
    if key not in sections:
        raise FormatError(None, f"corrupted pattern stream (missing section {key!r})")
    return sections[key]


def decode_clip(header: ClipHeader, hier: Hierarchy, sections: dict[str, bytes],
                dbs: dict[int, np.ndarray], priors: dict[int, np.ndarray] | None = None) -> Any:
    """Rebuild one clip from its own sections and the decoded pattern databases of its nodes.

    Args:
        header: the clip's header (skeleton or marker labels, frame count...).
        hier: the hierarchy.
        sections: the clip's sections (``p``, ``r``, ``g``, ``c``, ``s<k>``).
        dbs: node index -> decoded patterns ``(K, L, D)``.
        priors: node index -> shared pattern usage counts (library mode), or None.
    """
    frames = header.frames
    if frames == 0:
        return header.motion(np.zeros(header.value_shape))
    if header.skeleton is None:
        return header.motion(_decode_markers(header, hier, sections, dbs, priors, frames))
    return header.motion(_decode_skeletal(header, hier, sections, dbs, priors, frames))


def _node_values(k: int, width: int, sections: dict[str, bytes], dbs: dict[int, np.ndarray],
                 priors: dict[int, np.ndarray] | None, frames: int, observed: np.ndarray | None = None) -> np.ndarray:
    """Node ``k``'s decoded values ``(frames, width)``."""
    patterns = dbs[k]
    if patterns.shape[2] != width:
        raise FormatError(None, f"corrupted pattern stream (node {k} has patterns of {patterns.shape[2]} values "
                                f"where its members have {width})")
    labels, lengths = decode_segments(_need(sections, f"s{k}"), len(patterns),
                                      None if priors is None else priors.get(k), frames)
    if int(lengths.sum()) != frames:
        raise FormatError(None, f"corrupted pattern stream (node {k} covers {int(lengths.sum())} of {frames} frames)")
    return reconstruct(patterns, labels, lengths, observed)


def _decode_markers(header, hier, sections, dbs, priors, frames) -> np.ndarray:
    m = len(header.labels)
    params = _need(sections, "p")
    if len(params) != 2 or params[0] & ~FLAG_HEADING or params[1] > 2:
        raise FormatError(None, f"corrupted pattern stream (parameters {params[:8].hex()})")
    flags, up = params
    root, _ = decode_trajectory(_need(sections, "r"), (frames, 4 if flags & FLAG_HEADING else 3))
    yaw = root[:, 3] if flags & FLAG_HEADING else None
    missing = decode_mask(sections["g"], frames, m) if "g" in sections else None
    out = np.zeros((frames, m, 3))
    out[:, hier.nodes[0].reference] = root[:, :3]
    for k, node in enumerate(hier.nodes[1:], start=1):
        ref = hier.nodes[node.parent].reference
        obs = None if missing is None or not missing[:, node.members].any() else ~missing[:, node.members]
        x = _node_values(k, 3 * len(node.members), sections, dbs, priors, frames, obs)
        x = x.reshape(frames, len(node.members), 3)
        if yaw is not None:
            x = rotate(x, yaw, up)
        out[:, node.members] = x + out[:, ref][:, None]
    if missing is not None:
        out[missing] = np.nan
    return out


def _decode_skeletal(header, hier, sections, dbs, priors, frames) -> np.ndarray:
    sk = header.skeleton
    const = sections.get("c", b"")
    sf = SkeletalFeatures(sk, 0.0, SkeletalFeatures.varying_from(const, sk.n_channels))
    root = sf.decode_root(_need(sections, "r"), frames)  # checked against the frame count before allocating
    out = sf.apply_constants(np.zeros((frames, sk.n_channels)), const)
    out[:, sf.root_columns] = root
    for k, node in enumerate(hier.nodes[1:], start=1):
        sf.put_node(out, node.members, _node_values(k, sf.width(node.members), sections, dbs, priors, frames))
    return out
