"""Game-engine style baseline (how ACL and engine animation codecs work): every frame kept, each track
quantised uniformly at a bit rate chosen from an error threshold, then entropy coded.

Encoder: the value matrix (:mod:`.common`; rotation channels unwrapped) is split into tracks (columns).
From the position error threshold ``max_error`` each track gets a tolerance (:func:`tolerances`) such
that the sum of the worst-case displacements all tracks cause on any body point stays within
``max_error``; the track's quantisation step is the largest step ``2 ** (code / 8)`` not above twice its
tolerance, so every decoded sample is within the tolerance of the original. The track's integers are
range reduced (minus their minimum, stored as a varint); their range gives the track's bit rate (0 bits:
a constant track). The samples of every non-constant track are stored as time differences, **entropy
coded** with the range coder of :mod:`mocapz.format.entropy` (block-adaptive Laplace models).

The model alone (:func:`encode` / :func:`decode`): ``max_error`` is its position error threshold, file
units or with a unit (``"1cm"``, ``"4mm"``); default 1 mm when the file's unit is known, else 1/1000 of
the clip's bounding-box diagonal. The registered codec (``INFO``) wraps it in the correction layer
(:mod:`mocapz.codecs.correction`), which meets the targets and keeps whichever of the model or the
correction alone is smaller.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mocapz.codecs import CodecInfo
from mocapz.codecs.baselines.common import finish, gaps_bytes, gaps_from, layout_columns, values_of
from mocapz.codecs.correction.wrap import apply_window, corrected
from mocapz.codecs.ratesearch import coarsest_meeting
from mocapz.codecs.target import TARGET_OPTIONS, Target
from mocapz.errors import FormatError
from mocapz.format.entropy import decode_int_matrix, encode_int_matrix, pack_uint64, unpack_uint64, unzigzag, zigzag
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, Motion
from mocapz.model.skeleton import Skeleton

VERSION = 3  # 2: the correction layer (codecs/correction); 3: its knots and details in two streams
OPTIONS = TARGET_OPTIONS  # max_error is the codec's own threshold (default: 1 mm); the others are searched
SEARCH_STEPS = 48  # thresholds tried for a distortion / ARMS target: 2**-(i/2) of the cap, i < SEARCH_STEPS
CODE_BIAS = 160  # step = 2 ** ((code - CODE_BIAS) / 8), code in 0..255 (steps 2^-20 .. 2^11.9)
SAFETY = 0.99  # share of max_error handed out (second-order effects of the rotation bound)


def step_of(code: np.ndarray) -> np.ndarray:
    """Quantisation steps ``(tracks,)`` of step codes."""
    return 2.0 ** ((np.asarray(code, dtype=np.float64) - CODE_BIAS) / 8.0)


def code_for(tol: np.ndarray) -> np.ndarray:
    """Largest step code whose step is at most ``2 * tol`` (``(tracks,)`` uint8, clipped to 0..255)."""
    with np.errstate(divide="ignore"):
        c = np.floor(8.0 * np.log2(2.0 * np.asarray(tol, dtype=np.float64))) + CODE_BIAS
    c = np.where(np.isnan(c), 0, c)
    c = np.clip(c, 0, 255).astype(np.int64)
    # guard the float rounding of log2: step must not exceed 2 * tol
    over = step_of(c) > 2.0 * np.asarray(tol)
    c[over & (c > 0)] -= 1
    return c.astype(np.uint8)


def skeleton_tolerances(sk: Skeleton, channels: np.ndarray, max_error: float) -> np.ndarray:
    """Per-track tolerance ``(channels,)`` in the track's unit (file length unit or angle unit).

    A rotation error of ``d`` radians at joint ``a`` moves a descendant point by at most ``d * R_a``,
    ``R_a`` the longest chain length from ``a`` down to a point; a translation error moves the joint's
    subtree by at most its size. Each non-constant track ``c`` gets the displacement budget
    ``max_error / N_c``, ``N_c`` the most non-constant tracks acting on any one point it moves, so that
    on every point the budgets add up to at most ``max_error``.
    """
    n_j = sk.n_joints
    parents = sk.point_parents
    n_p = sk.n_points
    # longest local translation of every point over the clip (position channels replace offsets)
    from mocapz.model.kinematics import local_translations

    trans = local_translations(sk, channels) if len(channels) else np.broadcast_to(sk.offsets, (1, n_j, 3))
    seg = np.zeros(n_p)
    seg[:n_j] = np.linalg.norm(trans, axis=2).max(axis=0)
    for e, (_, off, _) in enumerate(sk.end_sites):
        seg[n_j + e] = float(np.linalg.norm(off))
    depth = np.zeros(n_p)  # chain length from the root down to each point
    for p in range(n_p):
        depth[p] = seg[p] + (depth[parents[p]] if parents[p] >= 0 else 0.0)
    # ancestors[p]: joints on the path root..p (p itself included when p is a joint)
    below = sk.below()  # below[a, p]: p strictly below joint a
    active = np.ptp(channels, axis=0) > 0 if len(channels) else np.zeros(sk.n_channels, dtype=bool)
    cols_joint, cols_rot = [], []
    for j, chs in enumerate(sk.channels):
        for c in chs:
            cols_joint.append(j)
            cols_rot.append(c.endswith("rotation"))
    joint = np.array(cols_joint, dtype=np.int64)
    is_rot = np.array(cols_rot, dtype=bool)
    affects = np.zeros((sk.n_channels, n_p), dtype=bool)
    for c in range(sk.n_channels):
        affects[c] = below[joint[c]]
        if not is_rot[c]:
            affects[c, joint[c]] = True
    n_acting = (affects & active[:, None]).sum(axis=0)  # (points,)
    radius = np.where(below, depth[None, :] - depth[:n_j, None], 0.0).max(axis=1, initial=0.0)  # (joints,)
    per_unit = math.pi / 180.0 if sk.angle_unit == "deg" else 1.0
    tol = np.full(sk.n_channels, np.inf)
    for c in range(sk.n_channels):
        if not affects[c].any():
            continue  # moves no point (e.g. a leaf's rotation): any value will do
        budget = SAFETY * max_error / max(1, int(n_acting[affects[c]].max()))
        if is_rot[c]:
            r = radius[joint[c]]
            tol[c] = budget / (r * per_unit) if r > 0 else np.inf
        else:
            tol[c] = budget
    return tol


def tolerances(motion: AnyMotion, max_error: float) -> np.ndarray:
    """Per-track tolerance ``(columns,)`` for a position error threshold ``max_error`` (file units).

    Skeletons: see :func:`skeleton_tolerances`. Markers: ``max_error / sqrt(3)`` per coordinate.
    """
    if isinstance(motion, Motion):
        return skeleton_tolerances(motion.skeleton, motion.channels, max_error)
    return np.full(3 * motion.n_markers, SAFETY * max_error / math.sqrt(3.0))


def default_error(motion: AnyMotion) -> float:
    """1 mm in file units when the unit is known, else 1/1000 of the bounding-box diagonal."""
    unit_cm = motion.skeleton.unit_cm if isinstance(motion, Motion) else motion.unit_cm
    if unit_cm:
        return 0.1 / unit_cm
    return 1e-3 * extent(motion)


def extent(motion: AnyMotion) -> float:
    """Diagonal of the clip's bounding box (file units; 1 for an empty or still clip)."""
    pos = motion.positions() if isinstance(motion, Motion) else motion.positions
    if not np.isfinite(pos).any():
        return 1.0
    with np.errstate(invalid="ignore"):
        ext = np.nanmax(pos.reshape(-1, 3), axis=0) - np.nanmin(pos.reshape(-1, 3), axis=0)
    diag = float(np.linalg.norm(np.nan_to_num(ext)))
    return diag if diag > 0 else 1.0


def encode(motion: AnyMotion, **options: Any) -> dict[str, bytes]:
    """Sections: ``code`` (step codes), ``bits`` (bit rate per track), ``qmin`` (range minima), ``q0``
    (first sample), ``dq`` (entropy-coded time differences), ``gaps`` (markers with gaps)."""
    target = Target.from_options(options, motion.unit_cm)
    if target.max_distortion is None and target.max_arms is None:
        return encode_threshold(motion, target.max_error or default_error(motion))
    cap = target.max_error or 0.1 * extent(motion)
    thresholds = [cap * 2.0 ** (-(SEARCH_STEPS - 1 - i) / 2) for i in range(SEARCH_STEPS)]
    return coarsest_meeting(motion, target, thresholds, lambda e: encode_threshold(motion, e), decode, "quant")


def encode_threshold(motion: AnyMotion, max_error: float) -> dict[str, bytes]:
    """Sections with every position error under ``max_error`` (file units)."""
    v = values_of(motion)
    code = code_for(tolerances(motion, max_error))
    q = np.round(v.x / step_of(code)).astype(np.int64)
    qmin = q.min(axis=0) if len(q) else np.zeros(q.shape[1], dtype=np.int64)
    span = (q.max(axis=0) - qmin) if len(q) else np.zeros(q.shape[1], dtype=np.int64)
    bits = np.array([int(s).bit_length() for s in span], dtype=np.uint64)
    act = bits > 0
    sections = {
        "code": pack_uint64(code.astype(np.uint64)),
        "bits": pack_uint64(bits),
        "qmin": pack_uint64(zigzag(qmin)),
    }
    if act.any():
        sections["q0"] = pack_uint64((q[0, act] - qmin[act]).astype(np.uint64))
        sections["dq"] = encode_int_matrix(np.diff(q[:, act], axis=0))
    if v.gaps is not None:
        sections["gaps"] = gaps_bytes(v.gaps)
    return sections


def decode(sections: dict[str, bytes], header: ClipHeader) -> AnyMotion:
    """Inverse of :func:`encode`: integers times their track's step."""
    frames = header.frames
    cols, _, _ = layout_columns(header)
    try:
        code = unpack_uint64(sections["code"], cols)
        bits = unpack_uint64(sections["bits"], cols)
        qmin = unzigzag(unpack_uint64(sections["qmin"], cols))
        if np.any(code > 255):
            raise FormatError(None, "corrupted quant stream (track step codes)")
        act = bits > 0
        n_act = int(act.sum())
        moving = None
        if n_act and frames:  # read (and checked against the header) before frames x columns are allocated
            q0 = unpack_uint64(sections["q0"], n_act).astype(np.int64)
            dq = decode_int_matrix(sections["dq"], (frames - 1, n_act))
            moving = qmin[act] + q0 + np.concatenate([np.zeros((1, n_act), np.int64), np.cumsum(dq, axis=0)])
        q = np.broadcast_to(qmin, (frames, cols)).copy()
        if moving is not None:
            q[:, act] = moving
    except KeyError as exc:
        raise FormatError(None, f"corrupted quant stream (missing section {exc})") from None
    x = q * step_of(code)
    return finish(header, x, gaps_from(sections, header), round_decimals=False)


def track_bits(sections: dict[str, bytes]) -> np.ndarray:
    """Bit rate of every track ``(tracks,)`` from encoded sections (for reports)."""
    return unpack_uint64(sections["bits"]).astype(np.int64)


# the correction's closed-loop lifting quantiser alone beat this model (a step per channel) as a base on every shared
# file tried (CMU BVH, ASF/AMC, Bandai-Namco, C3D, TRC): the model is the base only with settings the user gives
ENCODE, DECODE = corrected(encode, decode, "quant", OPTIONS, model_base=False)
INFO = CodecInfo(name="quant", version=VERSION, kinds=("skeleton", "markers"), encode=ENCODE, decode=DECODE,
                 options=OPTIONS, decode_window=apply_window,
                 summary="baseline: per-track quantisation of every frame under a position "
                                          "error bound (as ACL and game engines do): with a target, the correction "
                                          "layer's closed-loop lifting alone; with a step, uniform steps corrected")



